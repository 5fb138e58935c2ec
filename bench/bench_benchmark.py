"""Time of a benchmark run (issue 13's target: the default suite with the oracle in <= 10 minutes, 2 workers).

    python bench/bench_benchmark.py [--model oracle] [--workers 2] [--suite FILE] [--routes A,B] [--shm] [--json F]
    python bench/bench_benchmark.py --plot runs/bench/leaderboard.json --out docs/img/benchmark-scores.png

Runs `drivestudio benchmark` once and prints the wall time, the simulated time driven and, per model, the driving
score, route completion, collisions and off-road events, from the run's leaderboard.json. With --plot, draws the
driving score of every model on every route of a finished run instead.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", action="append", help="oracle (default) or a checkpoint; repeatable")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--suite", help="suite file (default: the shipped one)")
    ap.add_argument("--routes", help="comma-separated route names: drive only these (default: the whole suite)")
    ap.add_argument("--shm", action="store_true", help="drivers over shared memory")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    ap.add_argument("--plot", help="a leaderboard.json to draw (nothing is run)")
    ap.add_argument("--out", help="the PNG --plot writes")
    args = ap.parse_args()
    if args.plot:
        plot(json.loads(Path(args.plot).read_text()), args.out or "benchmark-scores.png")
        return
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "drivestudio", "benchmark", "--workers", str(args.workers), "--out", tmp]
        for m in args.model or ["oracle"]:
            cmd += ["--model", m]
        cmd += (["--suite", args.suite] if args.suite else []) + (["--shm"] if args.shm else [])
        cmd += ["--routes", args.routes] if args.routes else []
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        board = json.loads((Path(tmp) / "leaderboard.json").read_text())
    routes = [r for r in board["suite"]["routes"] if not args.routes or r["name"] in args.routes.split(",")]
    sim = sum(r["seconds"] for r in routes) * len(board["models"])
    print(f"suite '{board['suite']['name']}': {len(routes)} routes x {len(board['models'])} models, "
          f"{sim / 60:.1f} simulated minutes; {wall:.0f} s wall with {args.workers} workers "
          f"({board['run']['transport']}), {sim / wall:.1f}x real time")
    print("| model | driving score | completion | collisions | off-road | km |")
    print("|---|---|---|---|---|---|")
    for e in board["models"]:
        o = e["overall"]
        print(f"| {e['model']} | {o['driving_score']:.1%} | {o['route_completion']:.1%} | {o['collisions']} | "
              f"{o['off_road_events']} | {o['distance_km']:.1f} |")
    if args.json:
        args.json.write_text(json.dumps({
            "suite": board["suite"]["name"], "routes": [r["name"] for r in routes], "workers": args.workers,
            "transport": board["run"]["transport"], "wall_s": wall, "simulated_s": sim, "realtime_factor": sim / wall,
            "models": [{"model": e["model"], **{k: e["overall"][k] for k in ("driving_score", "route_completion",
                                                                              "collisions", "off_road_events",
                                                                              "distance_km")}}
                       for e in board["models"]]}, indent=2) + "\n")


def plot(board: dict, out: str) -> None:
    """Grouped bars: the driving score of each model on each route, and overall."""
    import matplotlib  # lazy: 0.7 s that only --plot needs
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # lazy: as matplotlib

    routes = [r["name"] for r in board["suite"]["routes"]] + ["suite"]
    models = board["models"]
    x = np.arange(len(routes))
    width = 0.8 / len(models)
    fig, ax = plt.subplots(figsize=(12, 3.8), dpi=100)
    for i, e in enumerate(models):
        scores = [r["driving_score"] * 100 for r in e["routes"]] + [e["overall"]["driving_score"] * 100]
        ax.bar(x + (i - (len(models) - 1) / 2) * width, scores, width, label=e["model"])
    ax.set_xticks(x, routes, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("driving score [%]")
    ax.set_ylim(0, 105)
    ax.set_title(f"suite '{board['suite']['name']}': driving score per route (RC x 0.60^collisions x "
                 f"0.65^off-road)", fontsize=10)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
