"""drivestudio generate --out DIR --frames N [--world W]: a labelled dataset of expert driving (docs/dataset.md)."""
from __future__ import annotations

import argparse
import os
import sys
import time

from core.files import check_output_dir
from drivestudio.commands.common import add_world_options, plugin_for, world_config
from drivestudio.commands.numbers import count, non_negative


def register(sub) -> None:
    p = sub.add_parser("generate", help="generate a labelled dataset (frames + exact ground truth) in shards",
                       description="Drive the world's expert (the highway: the perturbed Chen controller through SUMO "
                                   "traffic on many tracks) and record every step with its ground truth into Parquet "
                                   "shards. Running the same command again continues an interrupted run.")
    p.add_argument("--out", required=True, help="dataset folder")
    p.add_argument("--frames", type=count(1, 10**8), default=20000,
                   help="steps in the dataset (default 20000)")
    p.add_argument("--encoding", type=encoding, default=("png", 95), metavar="png|jpeg[:QUALITY]",
                   help="the frames' image format: png (lossless, the default) or jpeg at QUALITY 1-100 (default 95)")
    p.add_argument("--episode-frames", type=count(10, 10**6), default=None,
                   help="steps per episode and shard (default 500, shortened so that a small dataset still has "
                        "10 episodes and every split holds frames)")
    p.add_argument("--warmup", type=non_negative(600.0), default=None,
                   help="simulated seconds driven before an episode's recording starts (default 5)")
    p.add_argument("--workers", type=count(1, 256), default=os.cpu_count() or 1,
                   help="worker processes (default: cores)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local worker processes, or Ray tasks on a cluster (pip install 'drivestudio[cluster]')")
    add_world_options(p, "generate")
    p.set_defaults(func=run)


def run(args) -> int:
    from drivestudio.generate import GenerateConfig, episode_length, generate  # lazy: pyarrow (80 ms)

    plugin = plugin_for(args)
    check_output_dir(args.out, "dataset folder")
    config = world_config(plugin, args)
    # a bad track or mode fails here, in one line, before any work
    options = plugin.generate_options(config, args.world_options.values(plugin.name, args))
    # the renderer is a setting of a world that has a choice of them (--set renderer=NAME); the sidewalk paints its
    # own frames (sim/sidewalk/stereo.py)
    renderer = getattr(config, "renderer", "painter")
    cfg = GenerateConfig(world=plugin.name, frames=args.frames, seed=args.seed, renderer=renderer,
                         encoding=args.encoding[0], quality=args.encoding[1],
                         episode_frames=episode_length(args.frames, args.episode_frames),
                         warmup=5.0 if args.warmup is None else args.warmup, options=options)
    t0 = time.perf_counter()
    try:
        manifest = generate(args.out, cfg, workers=args.workers, backend=args.backend,
                            show_progress=sys.stderr.isatty())
    except KeyboardInterrupt:
        print("drivestudio generate: interrupted; run the same command again to continue", file=sys.stderr)
        return 130
    dt = time.perf_counter() - t0
    n = len(manifest["shards"])
    print(f"{manifest['frames']} frames in {n} episodes at {args.out} ({dt:.0f} s this run)"
          + ("" if manifest["complete"] else " - incomplete: run the same command again to continue"))
    return 0


def encoding(text: str) -> tuple[str, int]:
    """--encoding png | jpeg | jpeg:QUALITY, as (format, JPEG quality)."""
    name, _, quality = text.partition(":")
    if name not in ("png", "jpeg") or (quality and name == "png"):
        raise argparse.ArgumentTypeError(f"must be png, jpeg or jpeg:QUALITY, got {text!r}")
    if not quality:
        return name, 95
    return name, count(1, 100)(quality)
