"""Frames/s of rendering + ground truth: 3-lane preset, 12 cars in view, one process (issue 2's target: 100).

The host car drives along the track at 15 m/s while 12 scripted cars keep pace in the three lanes 8-80 m
ahead, so every frame has 12 cars in view and the scenery streams past as in a real run.

    python bench/bench_render.py [--track oval] [--frames 2000] [--renderer tiny|egl] [--mirror] [--side-views]
                                 [--json F]

--mirror adds the rear-view mirror (sim/mirror.py): a second, small view drawn per frame, with 4 scripted cars
behind the host as well. --side-views adds the views out of both side windows (and the mirror): two more small
views, with 2 more cars level with the host, one on each side.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from core.worlds.highway import Action
from sim.camera import RENDERERS
from sim.highway.scenario import scenario_from_dict
from sim.highway.world import World, WorldConfig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--track", default="oval")
    ap.add_argument("--frames", type=int, default=2000)
    ap.add_argument("--renderer", default="tiny", choices=RENDERERS)
    ap.add_argument("--mirror", action="store_true", help="with the rear-view mirror, and 4 cars behind")
    ap.add_argument("--side-views", action="store_true",
                    help="with the mirror and the side views, 4 cars behind and 2 level with the host")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    speed = 15.0
    cars = [{"s": 8.0 + 6.0 * i, "d": (4.0, 0.0, -4.0)[i % 3], "speed": speed} for i in range(12)]
    args.mirror = args.mirror or args.side_views
    if args.mirror:   # the same 12 ahead (the lap is long enough that none of them is behind) and 4 behind
        cars += [{"s": -10.0 - 8.0 * i, "d": (4.0, -4.0)[i % 2], "speed": speed} for i in range(4)]
    if args.side_views:
        cars += [{"s": 0.5, "d": d, "speed": speed} for d in (4.0, -4.0)]
    scenario = scenario_from_dict({"track": args.track, "lanes": 3, "seed": 1,
                                   "ego": {"s": 0.0, "d": 0.0, "speed": speed}, "cars": cars})
    config = WorldConfig(renderer=args.renderer, cars=0, mirror=args.mirror, side_views=args.side_views)
    with World(config, scenario=scenario) as world:
        obs = world.observe()
        in_view = []
        for _ in range(20):  # warm caches (and load a compiled renderer)
            obs = world.step(Action())
        world.timings = dict.fromkeys(world.timings, 0.0)   # the breakdown below is of the timed frames only
        t0 = time.perf_counter()
        for _ in range(args.frames):
            ind = obs.truth.indicators
            # hold the centre lane: steer on the true angle and offset (keeps cars in the same place in view)
            steer = float(np.clip((ind[0] - obs.truth.ego[4] / 8) / 0.541052, -1, 1))
            obs = world.step(Action(steer, 0.2 if obs.truth.speed < speed else 0.0, 0.0))
            in_view.append(int(np.sum(world.track.gap(world.ego.s, obs.truth.cars[:, 3]) > 0)))
        dt = time.perf_counter() - t0
        t = world.timings
    insets = (", mirror" if args.mirror else "") + (", side views" if args.side_views else "")
    print(f"track {args.track}, 3 lanes, renderer {args.renderer}{insets}, "
          f"{args.frames} frames of "
          f"{obs.frame.shape[1]}x{obs.frame.shape[0]}, cars ahead per frame: {np.mean(in_view):.1f}")
    print(f"render + ground truth: {args.frames / dt:.1f} frames/s ({dt / args.frames * 1e3:.2f} ms/frame; "
          f"render {t['render'] / args.frames * 1e3:.2f} ms, "
          f"truth {t['truth'] / args.frames * 1e3:.2f} ms,"
          f" physics {t['physics'] / args.frames * 1e3:.2f} ms)")
    if args.json:
        args.json.write_text(json.dumps({
            "track": args.track, "renderer": args.renderer, "mirror": args.mirror, "side_views": args.side_views,
            "frames": args.frames,
            "size": [int(obs.frame.shape[1]), int(obs.frame.shape[0])], "cars_ahead": float(np.mean(in_view)),
            "frames_per_s": args.frames / dt, "ms_per_frame": dt / args.frames * 1e3,
            "render_ms": t["render"] / args.frames * 1e3, "truth_ms": t["truth"] / args.frames * 1e3,
            "physics_ms": t["physics"] / args.frames * 1e3}, indent=2) + "\n")


if __name__ == "__main__":
    main()
