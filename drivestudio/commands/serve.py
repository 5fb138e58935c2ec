"""drivestudio serve --shm NAME: the world side of the shared-memory loop (TORCS's role), for any world."""
from __future__ import annotations

from core.files import check_output
from drivestudio.commands.common import (
    add_config_option,
    add_world_options,
    from_run,
    plugin_for,
    run_dir,
    run_seconds,
    world_config,
)
from drivestudio.commands.numbers import positive
from drivestudio.commands.studio import add_view_options, bind_view

MAX_SECONDS = 10 * 24 * 3600.0


def register(sub) -> None:
    p = sub.add_parser("serve", help="run the world and publish frames + truth over shared memory",
                       description="Create the shared-memory segment NAME, describe the world in its header, wait "
                                   "for a driver (`drivestudio drive --shm NAME`, or your own program: "
                                   "docs/shm-protocol.md), then step the world on its actions.")
    p.add_argument("--shm", required=True, help="name of the shared-memory segment (/dev/shm/NAME)")
    add_world_options(p, "serve")
    add_config_option(p)
    p.add_argument("--seconds", type=positive(MAX_SECONDS),
                   help="simulated seconds to run (default: until Ctrl-C)")
    p.add_argument("--realtime", action="store_true", help="pace to wall-clock time (default: as fast as it can)")
    p.add_argument("--free-running", action="store_true",
                   help="never wait for the driver; use its newest action (default: lock-step)")
    p.add_argument("--wait", type=positive(24 * 3600.0), default=120.0,
                   help="seconds to wait for a driver to attach (default 120)")
    p.add_argument("--record", help="write a video of the run (.mp4)")
    p.add_argument("--out", help="folder for metrics.json / metrics.md (default runs/serve-TIME)")
    add_view_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from drivestudio.drive_session import Run, run_world_side  # lazy: the bridge, only when it runs (not --help)
    from shm_bridge.segment import validate_name  # lazy: the bridge, only when it runs (not for --help)
    validate_name(args.shm)
    plugin = plugin_for(args)
    if args.record:
        check_output(args.record, (".mp4",), "video")
    run = Run(plugin, world_config(plugin, args), None, seconds=run_seconds(args, None, MAX_SECONDS),
              realtime=bool(from_run(args, "realtime", False)),
              free_running=bool(from_run(args, "free_running", False)), record=args.record, wait=args.wait,
              shm=args.shm, view=bind_view(args))
    return run_world_side(run, run_dir(args.out, "serve"))
