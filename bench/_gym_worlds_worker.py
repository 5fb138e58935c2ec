"""One timed run of bench/bench_gym_worlds.py, in its own process, against whichever source tree PYTHONPATH names
(this one, or an older commit exported for the before/after comparison): so it uses only what every version has,
gym.make("drivestudio/Highway-v0", ...) and the Chen controller, unless asked for more.

    PYTHONPATH=TREE python bench/_gym_worlds_worker.py --steps 300 [--worlds 2] [--observation affordances]
                                                     [--renderer numba]

K worlds (--worlds) step in turn in this one process, each driven by the Chen controller on its true indicators,
reset (next seed) when its episode ends; resets are timed apart. Prints one JSON line: steps, seconds, steps/s of
all worlds together (wall time, and this process's CPU time, which other work on a shared machine inflates less),
each world's SUMO transport.
"""
from __future__ import annotations

import argparse
import json
import time

import gymnasium as gym
import numpy as np

import sim  # noqa: F401  registers drivestudio/Highway-v0
from controller.highway import ChenController


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=300, help="steps of each world")
    ap.add_argument("--worlds", type=int, default=1)
    ap.add_argument("--warmup", type=int, default=20)
    ap.add_argument("--observation", default=None, help="camera (the default) or affordances (newer trees)")
    ap.add_argument("--renderer", default=None, help="the world's renderer (default: the environment's)")
    args = ap.parse_args()
    extra = {} if args.observation is None else {"observation": args.observation}
    if args.renderer is not None:
        extra["renderer"] = args.renderer
    envs = [gym.make("drivestudio/Highway-v0", track="oval", lanes=3, cars=12, **extra) for _ in range(args.worlds)]
    seeds = list(range(args.worlds))
    infos, ctrls = [], []
    for env, seed in zip(envs, seeds):
        _, info = env.reset(seed=seed)
        infos.append(info)
        ctrls.append(ChenController(info["lanes"]))

    def step(i: int) -> float:
        """One step of world i; the seconds its reset took, if its episode ended."""
        a = ctrls[i].act(infos[i]["indicators"], infos[i]["speed"])
        _, _, terminated, truncated, infos[i] = envs[i].step(np.array([a.steer, a.accel, a.brake], np.float32))
        if not (terminated or truncated):
            return 0.0
        t0 = time.perf_counter()
        seeds[i] += args.worlds
        _, infos[i] = envs[i].reset(seed=seeds[i])
        ctrls[i] = ChenController(infos[i]["lanes"])
        return time.perf_counter() - t0

    for _ in range(args.warmup):
        for i in range(args.worlds):
            step(i)
    t0, c0 = time.perf_counter(), time.process_time()
    resets = 0.0
    for _ in range(args.steps):
        for i in range(args.worlds):
            resets += step(i)
    seconds = time.perf_counter() - t0 - resets
    cpu = time.process_time() - c0 - resets   # this process's CPU: what a busy machine's waiting does not inflate
    transports = [getattr(getattr(getattr(e.unwrapped, "_world", None), "_traffic", None), "transport", "libsumo")
                  for e in envs]
    for env in envs:
        env.close()
    total = args.steps * args.worlds
    print(json.dumps({"steps": total, "seconds": round(seconds, 4), "steps_per_s": round(total / seconds, 1),
                      "steps_per_cpu_s": round(total / cpu, 1),
                      "worlds": args.worlds, "transports": transports}))


if __name__ == "__main__":
    main()
