"""highway-env's side of bench/bench_highway_env.py: runs in highway-env's own virtual environment (not ours) and
steps `highway-v0` when asked to, reporting its timings as JSON lines.

    .venv-highway-env/bin/python bench/_highway_env_worker.py --seed 0

Protocol (one JSON object a line): it first writes {"ready": true, "versions": {...}, "config": {...}}; then for
each line {"steps": N} on stdin it runs N steps (IDLE action, a `rgb_array` render after every step, a reset
after each episode's end) and writes {"steps": N, "seconds": s, "reset_seconds": r, "resets": k, "frame": [h, w,
3]}: `seconds` is the time of the steps and renders alone, resets are timed apart. It exits at the end of stdin.
Imports nothing of drivestudio.
"""
from __future__ import annotations

import argparse
import importlib.metadata
import json
import os
import sys
import time
from typing import Any

import numpy as np

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")


def _rgb(frame) -> np.ndarray:
    assert isinstance(frame, np.ndarray)   # render_mode="rgb_array" renders an array
    return frame


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lanes", type=int, default=3)
    ap.add_argument("--vehicles", type=int, default=12)
    ap.add_argument("--width", type=int, default=280)
    ap.add_argument("--height", type=int, default=210)
    ap.add_argument("--policy-frequency", type=int, help="decisions per simulated second (highway-v0's default: 1)")
    args = ap.parse_args()

    out = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)   # pygame's and gymnasium's chatter must not corrupt the protocol

    # lazy: after the redirection above, as importing highway_env prints pygame's banner
    import gymnasium as gym
    import highway_env  # noqa: F401  registers highway-v0

    config = {"lanes_count": args.lanes, "vehicles_count": args.vehicles, "screen_width": args.width,
              "screen_height": args.height, "offscreen_rendering": True}
    if args.policy_frequency:
        config["policy_frequency"] = args.policy_frequency
    env = gym.make("highway-v0", render_mode="rgb_array", config=config)
    highway: Any = env.unwrapped   # highway-env's AbstractEnv: the checker runs where highway-env is not installed
    idle = highway.action_type.actions_indexes["IDLE"]
    seed = args.seed
    env.reset(seed=seed)
    frame = _rgb(env.render())

    versions: dict[str, str | None] = {}
    for pkg in ("highway-env", "gymnasium", "numpy", "pygame-ce"):
        try:
            versions[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            versions[pkg] = None
    versions["python"] = sys.version.split()[0]
    cfg = highway.config
    out.write(json.dumps({"ready": True, "versions": versions, "frame": list(frame.shape),
                          "config": {k: cfg[k] for k in ("lanes_count", "vehicles_count", "screen_width",
                                                         "screen_height", "policy_frequency",
                                                         "simulation_frequency", "duration")}}) + "\n")
    for line in sys.stdin:
        job = json.loads(line)
        steps, busy, reset_time, resets = int(job["steps"]), 0.0, 0.0, 0
        for _ in range(steps):
            t0 = time.perf_counter()
            _, _, terminated, truncated, _ = env.step(idle)
            frame = _rgb(env.render())
            busy += time.perf_counter() - t0
            if terminated or truncated:
                t0 = time.perf_counter()
                seed += 1
                env.reset(seed=seed)
                reset_time += time.perf_counter() - t0
                resets += 1
        out.write(json.dumps({"steps": steps, "seconds": busy, "reset_seconds": reset_time, "resets": resets,
                              "frame": list(frame.shape)}) + "\n")
    env.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
