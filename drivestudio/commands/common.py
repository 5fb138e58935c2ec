"""Options shared by the verbs that build a world (serve, drive, record)."""
from __future__ import annotations

import time
from pathlib import Path

from ..errors import UsageError


def add_world_options(p, cars_default: int = 12) -> None:
    g = p.add_argument_group("world")
    g.add_argument("--track", default=None, help="track preset, track file or procedural:SEED (default oval)")
    g.add_argument("--lanes", type=int, help="lane count 1-4 (default: the track's)")
    g.add_argument("--cars", type=int, default=cars_default, help=f"AI cars driven by SUMO (default {cars_default})")
    g.add_argument("--seed", type=int, default=0, help="seed of the scene and the traffic (default 0)")
    g.add_argument("--renderer", choices=("tiny", "egl"), default="tiny", help="PyBullet renderer (default tiny)")
    g.add_argument("--start-speed", type=float, default=15.0, help="host car's speed at the start [m/s]")


def world_config(args, render: bool):
    from sim.world import WorldConfig
    if args.lanes is not None and not 1 <= args.lanes <= 4:
        raise UsageError("--lanes must be from 1 to 4")
    return WorldConfig(track=args.track or "oval", lanes=args.lanes, cars=args.cars, seed=args.seed,
                       renderer=args.renderer, render=render, start_speed=args.start_speed)


def run_dir(out: str | None, prefix: str) -> Path:
    path = Path(out) if out else Path("runs") / f"{prefix}-{time.strftime('%Y%m%d-%H%M%S')}"
    path.mkdir(parents=True, exist_ok=True)
    return path


def load_perception(model: str, device: str = "cpu"):
    """None for the oracle (the truth itself), else a predictor loaded from a checkpoint."""
    if model == "oracle":
        return None
    if not Path(model).is_file():
        raise UsageError(f"--model must be 'oracle' or a checkpoint file; no such file: {model}")
    from perception.predictor import load_predictor
    return load_predictor(model, device=device)
