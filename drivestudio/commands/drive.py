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
from drivestudio.commands.common import (
    add_config_option,
    add_device_option,
    add_world_options,
    from_run,
    plugin_for,
    run_dir,
    run_seconds,
    world_config,
)
from drivestudio.commands.numbers import positive
from drivestudio.commands.studio import add_view_options, bind_view
from drivestudio.driver_spec import parse_driver
from drivestudio.errors import UsageError

DEFAULT_SECONDS = 60.0
MAX_SECONDS = 10 * 24 * 3600.0


def register(sub) -> None:
    p = sub.add_parser("drive", help="drive closed loop with a world's own driver or a trained model",
                       description=__doc__.split("\n", 1)[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", default=None, help="the driver: 'oracle' or 'oracle-extended' (highway), 'expert' "
                                                 "(sidewalk) or a checkpoint, with the world's estimate filters as "
                                                 "CKPT@smoothing=0.5,pass_memory=15 (default: the world's own "
                                                 "driver; docs/driving.md)")
    add_device_option(p, default=None)
    p.add_argument("--shm", help="attach to this running world (`drivestudio serve --shm NAME`) as its driver; the "
                                 "world and its options come from there")
    p.add_argument("--attach-wait", type=positive(24 * 3600.0), metavar="SECONDS",
                   help="with --shm: seconds to wait for the world's segment to appear (default 30)")
    add_world_options(p, "drive")
    add_config_option(p)
    p.add_argument("--seconds", type=positive(MAX_SECONDS), default=None,
                   help=f"simulated seconds (default {DEFAULT_SECONDS:g})")
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

    if args.shm is not None:
        check_device(args.device or "cpu")
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
        return drive_session.run_driver_side(args.shm, args.model, args.device or "cpu", args.seed or 0,
                                             args.attach_wait, args.stats_out)
    if args.attach_wait is not None:
        raise UsageError("--attach-wait goes with --shm (a driver attaching to a running world)")
    plugin = plugin_for(args)
    spec = plugin.parse_driver(from_run(args, "model", plugin.expert_names[0]))
    if args.record:
        check_output(args.record, (".mp4",), "video")
    plugin.check_driver(spec)   # before the world starts: one line, exit 2
    config = plugin.fit_driver(world_config(plugin, args), spec)   # what the driver decides (the mirror)
    run = drive_session.Run(plugin, config, spec, seconds=run_seconds(args, DEFAULT_SECONDS, MAX_SECONDS),
                            realtime=bool(from_run(args, "realtime", False)),
                            free_running=bool(from_run(args, "free_running", False)), record=args.record,
                            device=str(from_run(args, "device", "cpu")), view=bind_view(args))
    check_device(run.device)
    out = run_dir(args.out, "drive")
    if args.in_process:
        return drive_session.run_in_process(run, out)
    return drive_session.run_both_sides(run, out)
