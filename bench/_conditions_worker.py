"""One renderer's run of bench/bench_conditions.py, in a process of its own: a world per condition, warmed up, then
rounds of `--frames` frames of each condition in turn (the order reversed every other round, so that each sees the
same machine); prints one JSON line of every round's figures.

    python bench/_conditions_worker.py --renderer numba --conditions clear,night --frames 1000 --rounds 3
"""
from __future__ import annotations

import argparse
import json

from bench._render_worker import drive, world_for  # sets LP_NUM_THREADS before Mesa loads
from core.worlds.highway import Action
from sim.highway.errors import RendererError

SEED = 3   # a scene with street lamps (they light the road at night) and the sun ahead on part of the lap


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--renderer", required=True)
    ap.add_argument("--conditions", required=True)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--track", default="oval")
    ap.add_argument("--insets", default="none")
    args = ap.parse_args()
    names = args.conditions.split(",")
    out: dict = {"renderer": args.renderer, "runs": {n: [] for n in names}}
    try:
        worlds = {n: world_for(args.track, args.renderer, args.insets, n, SEED) for n in names}
        for world in worlds.values():
            for _ in range(20):   # warm caches, load (or compile) the renderer and the effects
                world.step(Action())
        for k in range(args.rounds):
            for n in (names if k % 2 == 0 else names[::-1]):
                out["runs"][n].append(drive(worlds[n], args.frames))
        for world in worlds.values():
            world.close()
    except RendererError as e:
        out["skipped"] = str(e)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
