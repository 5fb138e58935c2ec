"""drivestudio generate --out DIR --frames N: a labelled dataset of perturbed expert driving (docs/dataset.md)."""
from __future__ import annotations

import os
import sys
import time

from ..errors import UsageError


def _int_list(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise UsageError(f"expected comma-separated integers, got '{text}'") from None


def _range(text: str) -> tuple[int, int]:
    try:
        lo, _, hi = text.partition("-")
        lo_i = int(lo)
        return (lo_i, int(hi) if hi else lo_i)
    except ValueError:
        raise UsageError(f"expected N or A-B for --cars, got '{text}'") from None


def register(sub) -> None:
    p = sub.add_parser("generate", help="generate a labelled dataset (frames + exact indicators) in shards",
                       description="Drive the perturbed Chen expert through SUMO traffic on many tracks and record "
                                   "every 10 Hz frame with its ground truth into Parquet shards. Running the same "
                                   "command again continues an interrupted run.")
    p.add_argument("--out", required=True, help="dataset folder")
    p.add_argument("--frames", type=int, default=20000, help="frames in the dataset (default 20000)")
    p.add_argument("--tracks", help="comma-separated tracks: presets, files, procedural:SEED "
                                    "(default: every preset plus --procedural procedural tracks)")
    p.add_argument("--procedural", type=int, default=3, help="procedural tracks added to the default list (3)")
    p.add_argument("--lanes", default="1,2,3", help="lane counts to cycle through (default 1,2,3)")
    p.add_argument("--cars", default="12-30", help="AI cars per episode: N or a range A-B (default 12-30)")
    p.add_argument("--seed", type=int, default=0, help="seed of the whole plan (default 0)")
    p.add_argument("--renderer", choices=("tiny", "egl"), default="tiny")
    p.add_argument("--width", type=int, default=280)
    p.add_argument("--height", type=int, default=210)
    p.add_argument("--fov", type=float, default=60.0, help="vertical field of view [deg]")
    p.add_argument("--encoding", choices=("png", "jpeg"), default="png", help="png (lossless, default) or jpeg")
    p.add_argument("--quality", type=int, default=95, help="JPEG quality (default 95)")
    p.add_argument("--episode-frames", type=int, default=500, help="frames per episode and shard (default 500)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="worker processes (default: cores)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local worker processes, or Ray tasks on a cluster (pip install 'drivestudio[cluster]')")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args) -> int:
    from sim.track import load_track

    from ..generate import GenerateConfig, generate

    cars = _range(args.cars)
    lanes = _int_list(args.lanes)
    tracks = tuple(t.strip() for t in args.tracks.split(",") if t.strip()) if args.tracks else ()
    if args.frames < 1:
        raise UsageError("--frames must be at least 1")
    if not lanes or any(not 1 <= n <= 4 for n in lanes):
        raise UsageError("--lanes must list lane counts from 1 to 4")
    if not 0 <= cars[0] <= cars[1] <= 300:
        raise UsageError("--cars must be from 0 to 300 (and A <= B)")
    if args.episode_frames < 10:
        raise UsageError("--episode-frames must be at least 10")
    if args.workers < 1:
        raise UsageError("--workers must be at least 1")
    if not 16 <= args.width <= 4096 or not 16 <= args.height <= 4096:
        raise UsageError("--width and --height must be between 16 and 4096")
    if not 1 <= args.quality <= 100:
        raise UsageError("--quality must be from 1 to 100")
    cfg = GenerateConfig(frames=args.frames, tracks=tracks, procedural=args.procedural, lanes=lanes, cars=cars,
                         seed=args.seed, renderer=args.renderer, width=args.width, height=args.height, fov=args.fov,
                         encoding=args.encoding, quality=args.quality, episode_frames=args.episode_frames)
    for track in cfg.track_list():  # a bad track fails here, in one line, before any worker starts
        for n in set(lanes):
            load_track(track, lanes=n)
    t0 = time.perf_counter()
    try:
        manifest = generate(args.out, cfg, workers=args.workers, backend=args.backend, show_progress=not args.quiet)
    except KeyboardInterrupt:
        print("drivestudio generate: interrupted; run the same command again to continue", file=sys.stderr)
        return 130
    dt = time.perf_counter() - t0
    n = len(manifest["shards"])
    print(f"{manifest['frames']} frames in {n} episodes at {args.out} ({dt:.0f} s this run)"
          + ("" if manifest["complete"] else " - incomplete: run the same command again to continue"))
    return 0
