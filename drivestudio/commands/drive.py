"""drivestudio drive: the driver side of the loop, or both sides at once, for any world.

    drive --shm NAME --model M                             the driver, attached to a running `serve`
    drive --model M [--world W ...] --seconds S            world and driver as two processes over the bridge
    drive ... --in-process                                 the same loop in one process (no bridge)

M is one of the world's own drivers (highway: oracle; sidewalk: expert), a checkpoint of that world, or (highway)
a trained policy: a saved Stable-Baselines3 .zip or policy:MODULE:NAME (docs/gymnasium.md).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from core.files import check_output
from drivestudio import worlds
from drivestudio.checkpoints import check_checkpoint, check_device
from drivestudio.commands.common import add_device_option, add_world_options, plugin_for, run_dir
from drivestudio.commands.studio import add_view_options, bind_view
from drivestudio.driver_spec import parse_driver
from drivestudio.errors import UsageError
from drivestudio.numbers import positive


def register(sub) -> None:
    p = sub.add_parser("drive", help="drive closed loop with a world's own driver or a trained model",
                       description=__doc__.split("\n", 1)[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", default=None, help="the driver: 'oracle' or 'oracle-extended' (highway), 'expert' "
                                                 "(sidewalk) or a checkpoint, with the world's estimate filters as "
                                                 "CKPT@smoothing=0.5,pass_memory=15 (default: the world's own "
                                                 "driver; docs/driving.md)")
    add_device_option(p)
    p.add_argument("--shm", help="attach to this running world (`drivestudio serve --shm NAME`) as its driver; the "
                                 "world and its options come from there")
    p.add_argument("--attach-wait", type=positive(24 * 3600.0), metavar="SECONDS",
                   help="with --shm: seconds to wait for the world's segment to appear (default 30)")
    add_world_options(p, "drive")
    p.add_argument("--seconds", type=positive(10 * 24 * 3600.0), default=60.0,
                   help="simulated seconds (default 60)")
    p.add_argument("--realtime", action="store_true", help="pace to wall-clock time (default: as fast as it can)")
    p.add_argument("--free-running", action="store_true",
                   help="the world never waits for the driver (default: lock-step)")
    p.add_argument("--in-process", action="store_true", help="one process, no shared memory")
    p.add_argument("--record", help="write a video of the run (.mp4)")
    p.add_argument("--out", help="folder for metrics.json / metrics.md (default runs/drive-TIME)")
    p.add_argument("--stats-out", help=argparse.SUPPRESS)  # driver side: timings for the parent
    add_view_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from drivestudio import drive_session  # lazy: the bridge, only when it runs (not for --help)

    check_device(args.device)
    if args.shm is not None:
        given = [f for f in ("--record", "--in-process", "--free-running", "--view")
                 if getattr(args, f[2:].replace("-", "_"))]
        if given:
            raise UsageError(f"with --shm the world runs elsewhere: {', '.join(given)} do not apply")
        from shm_bridge.segment import validate_name  # lazy: the bridge, only when it runs (not for --help)
        validate_name(args.shm)
        if args.model is not None:   # the syntax now; the filters once the world's header names the world
            source = parse_driver(args.model).source
            if Path(source).is_file() and not any(p.own_model(source) for p in worlds.all_plugins()):
                check_checkpoint(source, None)   # a checkpoint: checked now
        return drive_session.run_driver_side(args.shm, args.model, args.device, args.seed, args.attach_wait,
                                             args.stats_out)
    if args.attach_wait is not None:
        raise UsageError("--attach-wait goes with --shm (a driver attaching to a running world)")
    plugin = plugin_for(args)
    args.driver = plugin.parse_driver(args.model or plugin.expert_names[0])
    args.model = args.driver.source
    if args.record:
        check_output(args.record, (".mp4",), "video")
    plugin.check_driver(args.driver)   # before the world starts: one line, exit 2
    plugin.resolve_args(args)        # what the model decides about its world (the highway's mirror)
    bind_view(args)
    out = run_dir(args.out, "drive")
    if args.in_process:
        return drive_session.run_in_process(args, plugin, out)
    return drive_session.run_both_sides(args, plugin, out)
