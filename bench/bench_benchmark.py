"""Time of a benchmark run (issue 13's target: the default suite with the oracle in <= 10 minutes, 2 workers).

    python bench/bench_benchmark.py [--model oracle] [--workers 2] [--suite FILE] [--shm]

Runs `drivestudio benchmark` once and prints the wall time, the simulated time driven and, per model, the driving
score, route completion, collisions and off-road events, from the run's leaderboard.json.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", action="append", help="oracle (default) or a checkpoint; repeatable")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--suite", help="suite file (default: the shipped one)")
    ap.add_argument("--shm", action="store_true", help="drivers over shared memory")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "drivestudio", "benchmark", "--workers", str(args.workers), "--out", tmp,
               "--quiet"]
        for m in args.model or ["oracle"]:
            cmd += ["--model", m]
        cmd += (["--suite", args.suite] if args.suite else []) + (["--shm"] if args.shm else [])
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        board = json.loads((Path(tmp) / "leaderboard.json").read_text())
    sim = sum(r["seconds"] for r in board["suite"]["routes"]) * len(board["models"])
    print(f"suite '{board['suite']['name']}': {len(board['suite']['routes'])} routes x {len(board['models'])} models, "
          f"{sim / 60:.1f} simulated minutes; {wall:.0f} s wall with {args.workers} workers "
          f"({board['run']['transport']}), {sim / wall:.1f}x real time")
    print("| model | driving score | completion | collisions | off-road | km |")
    print("|---|---|---|---|---|---|")
    for e in board["models"]:
        o = e["overall"]
        print(f"| {e['model']} | {o['driving_score']:.1%} | {o['route_completion']:.1%} | {o['collisions']} | "
              f"{o['off_road_events']} | {o['distance_km']:.1f} |")


if __name__ == "__main__":
    main()
