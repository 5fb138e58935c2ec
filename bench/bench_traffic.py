"""Simulation steps/s without rendering: world + SUMO + ground truth at 10 Hz (issue 3's target: 1000 with 12 cars).

The oracle (Chen controller on the exact indicators) drives the host car, as in a closed-loop run; its cost
is reported apart. Anchor: TORCS in results-only mode runs 10 AI cars ~106x faster than real time on this
machine, ~1000 steps/s at 10 Hz.

    python bench/bench_traffic.py [--track oval] [--lanes 3] [--cars 12 50 100] [--seconds 300]
"""
from __future__ import annotations

import argparse

from controller.metrics import ClosedLoopMetrics
from drivestudio.loop import Driver, in_process, run_loop
from sim.world import World, WorldConfig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--track", default="oval")
    ap.add_argument("--lanes", type=int, default=3)
    ap.add_argument("--cars", type=int, nargs="+", default=[12, 50, 100])
    ap.add_argument("--seconds", type=float, default=300.0, help="simulated seconds per run")
    args = ap.parse_args()
    print(f"track {args.track}, {args.lanes} lanes, {args.seconds:.0f} simulated s per run, no rendering")
    print("| AI cars | steps/s | x real time | world+SUMO+truth ms/step | driver ms/step |")
    print("|---|---|---|---|---|")
    for n in args.cars:
        with World(WorldConfig(track=args.track, lanes=args.lanes, cars=n, seed=0, render=False,
                               start_speed=15.0)) as world:
            driver = Driver()
            metrics = ClosedLoopMetrics(world.track.length, world.config.dt)
            run_loop(world, in_process(driver), args.seconds, render=False, metrics=metrics)
        r = metrics.report()
        driver_ms = sum(driver.timings.values()) / metrics.steps * 1e3
        sim_ms = 1e3 / r["loop_rate_hz"] - driver_ms
        print(f"| {n} | {r['loop_rate_hz']:.0f} | {r['realtime_factor']:.0f} | {sim_ms:.3f} | {driver_ms:.3f} |",
              flush=True)


if __name__ == "__main__":
    main()
