"""Simulation steps/s without rendering: world + SUMO + ground truth at 10 Hz (issue 3's target: 1000 with 12 cars).

The oracle (Chen controller on the exact indicators) drives the host car, as in a closed-loop run; its cost
is reported apart. Anchor: TORCS in results-only mode runs 10 AI cars ~106x faster than real time on this
machine, ~1000 steps/s at 10 Hz.

    python bench/bench_traffic.py [--track oval] [--lanes 3] [--cars 12 50 100] [--seconds 300] [--json F]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from controller.highway.metrics import HighwayMetrics
from drivestudio.loop import in_process, run_loop
from drivestudio.worlds.highway.drivers import ChenDriver
from sim.highway.world import World, WorldConfig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--track", default="oval")
    ap.add_argument("--lanes", type=int, default=3)
    ap.add_argument("--cars", type=int, nargs="+", default=[12, 50, 100])
    ap.add_argument("--seconds", type=float, default=300.0, help="simulated seconds per run")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    rows = []
    print(f"track {args.track}, {args.lanes} lanes, {args.seconds:.0f} simulated s per run, no rendering")
    print("| AI cars | steps/s | x real time | world+SUMO+truth ms/step | driver ms/step |")
    print("|---|---|---|---|---|")
    for n in args.cars:
        with World(WorldConfig(track=args.track, lanes=args.lanes, cars=n, seed=0, render=False,
                               start_speed=15.0)) as world:
            driver = ChenDriver(None)   # the oracle
            metrics = HighwayMetrics.of(world)
            run_loop(world, in_process(driver), args.seconds, render=False, metrics=metrics)
        r = metrics.report()
        driver_ms = sum(driver.timings.values()) / metrics.steps * 1e3
        sim_ms = 1e3 / r["loop_rate_hz"] - driver_ms
        print(f"| {n} | {r['loop_rate_hz']:.0f} | {r['realtime_factor']:.0f} | {sim_ms:.3f} | {driver_ms:.3f} |",
              flush=True)
        rows.append({"cars": n, "steps_per_s": r["loop_rate_hz"], "realtime_factor": r["realtime_factor"],
                     "sim_ms_per_step": sim_ms, "driver_ms_per_step": driver_ms})
    if args.json:
        args.json.write_text(json.dumps({"track": args.track, "lanes": args.lanes, "seconds": args.seconds,
                                         "runs": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
