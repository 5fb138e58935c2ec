"""drivestudio serve --shm NAME: the world side of the shared-memory loop (TORCS's role)."""
from __future__ import annotations

from .common import add_world_options, run_dir, world_config


def register(sub) -> None:
    p = sub.add_parser("serve", help="run the world and publish frames + truth over shared memory",
                       description="Create the shared-memory segment NAME, wait for a driver "
                                   "(`drivestudio drive --shm NAME`), then step the world on its actions. "
                                   "Protocol: docs/shm-protocol.md.")
    p.add_argument("--shm", required=True, help="name of the shared-memory segment (/dev/shm/NAME)")
    add_world_options(p)
    p.add_argument("--seconds", type=float, help="simulated seconds to run (default: until Ctrl-C)")
    p.add_argument("--realtime", action="store_true", help="pace to wall-clock 10 Hz (default: as fast as it can)")
    p.add_argument("--free-running", action="store_true",
                   help="never wait for the driver; use its newest action (default: lock-step)")
    p.add_argument("--wait", type=float, default=120.0, help="seconds to wait for a driver (default 120)")
    p.add_argument("--out", help="folder for metrics.json / metrics.md (default runs/serve-TIME)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..drive_session import run_world_side
    return run_world_side(args, world_config(args, render=True), run_dir(args.out, "serve"))
