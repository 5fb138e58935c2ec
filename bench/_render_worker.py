"""One renderer's run of bench/bench_render.py, in a process of its own (PyBullet's EGL plugin and OpenGL do not
share one): a world per inset, warmed up, then `--frames` frames each; prints one JSON line of the figures.

    python bench/_render_worker.py --renderer numba --insets none,mirror,sides --frames 1000 [--track oval]
"""
from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("LP_NUM_THREADS", "0")   # before anything loads Mesa: llvmpipe draws on this thread alone

import numpy as np  # noqa: E402  (below the thread setting, which Mesa reads when it loads)

from core.conditions import SEEDED  # noqa: E402
from core.worlds.highway import Action  # noqa: E402
from sim.highway.errors import RendererError  # noqa: E402
from sim.highway.scenario import scenario_from_dict  # noqa: E402
from sim.highway.world import World, WorldConfig  # noqa: E402

SPEED = 15.0   # [m/s]


def world_for(track: str, renderer: str, inset: str, condition: str = SEEDED, seed: int = 1) -> World:
    """12 cars 8-74 m ahead in three lanes; with the mirror 4 more behind, with the side views 2 more level; the
    scene of `seed`, drawn in `condition` (docs/conditions.md)."""
    cars = [{"s": 8.0 + 6.0 * i, "d": (4.0, 0.0, -4.0)[i % 3], "speed": SPEED} for i in range(12)]
    if inset != "none":   # the same 12 ahead (the lap is long enough that none of them is behind) and 4 behind
        cars += [{"s": -10.0 - 8.0 * i, "d": (4.0, -4.0)[i % 2], "speed": SPEED} for i in range(4)]
    if inset == "sides":
        cars += [{"s": 0.5, "d": d, "speed": SPEED} for d in (4.0, -4.0)]
    scenario = scenario_from_dict({"track": track, "lanes": 3, "seed": seed,
                                   "ego": {"s": 0.0, "d": 0.0, "speed": SPEED}, "cars": cars})
    return World(WorldConfig(renderer=renderer, cars=0, mirror=inset != "none", side_views=inset == "sides",
                             condition=condition), scenario=scenario)


def drive(world: World, frames: int) -> dict:
    """`frames` steps with a frame each, holding the centre lane: frames a second of wall and of CPU time, and the
    world's breakdown [ms a frame]."""
    obs = world.observe()
    world.timings = dict.fromkeys(world.timings, 0.0)
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(frames):
        ind = obs.truth.indicators
        # steer on the true angle and offset: the cars stay where they are in view
        steer = float(np.clip((ind[0] - obs.truth.ego[4] / 8) / 0.541052, -1, 1))
        obs = world.step(Action(steer, 0.2 if obs.truth.speed < SPEED else 0.0, 0.0))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"frames_per_s": frames / wall, "frames_per_cpu_s": frames / cpu,
            **{f"{k}_ms": world.timings[k] / frames * 1e3 for k in ("render", "truth", "physics")}}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--renderer", required=True)
    ap.add_argument("--insets", default="none,mirror,sides")
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--track", default="oval")
    args = ap.parse_args()
    out: dict = {"renderer": args.renderer, "runs": {}}
    try:
        for inset in args.insets.split(","):
            with world_for(args.track, args.renderer, inset) as world:
                for _ in range(20):   # warm caches, load (or compile) the renderer
                    world.step(Action())
                out["runs"][inset] = drive(world, args.frames)
    except RendererError as e:
        out["skipped"] = str(e)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
