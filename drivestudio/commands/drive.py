"""drivestudio drive: the driver side of the loop, or both sides at once.

    drive --shm NAME --model oracle|CKPT                   the driver, attached to a running `serve`
    drive --model oracle|CKPT --track T --seconds S        world and driver as two processes over the bridge
    drive ... --in-process                                 the same loop in one process (no bridge)
"""
from __future__ import annotations

from ..errors import UsageError
from .common import add_world_options, run_dir, world_config


def register(sub) -> None:
    p = sub.add_parser("drive", help="drive closed loop with the oracle or a trained model",
                       description=__doc__.split("\n", 1)[1], formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    p.add_argument("--model", default="oracle", help="'oracle' (perfect perception) or a checkpoint (default oracle)")
    p.add_argument("--device", default="cpu", help="torch device for a model (default cpu)")
    p.add_argument("--shm", help="attach to this running world (`drivestudio serve --shm NAME`) as its driver")
    add_world_options(p)
    p.add_argument("--seconds", type=float, default=60.0, help="simulated seconds (default 60)")
    p.add_argument("--realtime", action="store_true", help="pace to wall-clock 10 Hz (default: as fast as it can)")
    p.add_argument("--free-running", action="store_true",
                   help="the world never waits for the driver (default: lock-step)")
    p.add_argument("--in-process", action="store_true", help="one process, no shared memory")
    p.add_argument("--record", help="write the run's box overlays (truth and estimate) as this .mp4")
    p.add_argument("--out", help="folder for metrics.json / metrics.md (default runs/drive-TIME)")
    p.add_argument("--stats-out", help=__import__("argparse").SUPPRESS)  # driver side: timings for the parent
    p.set_defaults(func=run)


def run(args) -> int:
    from .. import drive_session
    from .common import load_perception

    world_given = any(getattr(args, k) is not None for k in ("track", "lanes"))
    if args.shm and (world_given or args.in_process or args.record):
        raise UsageError("with --shm the world runs elsewhere: --track, --lanes, --in-process and --record do "
                         "not apply")
    perception = load_perception(args.model, args.device)
    if args.shm:
        return drive_session.run_driver_side(args.shm, perception, args.stats_out)
    cfg = world_config(args, render=args.model != "oracle" or not args.in_process or bool(args.record))
    out = run_dir(args.out, "drive")
    if args.in_process:
        return drive_session.run_in_process(args, cfg, perception, out)
    return drive_session.run_both_sides(args, cfg, out)
