"""Benchmark of the shared-memory bridge between two real processes.

Lock-step round trip: the world publishes a frame (the highway: one 280x210x3 image; the sidewalk: a stereo pair
of 336x188x3 images) with its truth record, a driver process copies it out and answers with an action, the world
reads the action. Prints the median, p90, p99 and max round-trip latency and the round trips per second; then the
free-running rates (frames published by a world that never waits, frames taken by a driver that always takes the
newest).

    .venv/bin/python bench/bench_bridge.py [--world highway|sidewalk] [--trips 5000] [--spin 100e-6] [--json F]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from core import worlds  # noqa: E402
from shm_bridge.endpoints import DriverEndpoint, WorldEndpoint  # noqa: E402


def run_driver(name: str, spin: float) -> int:
    """The driver process: answer every frame at once (no network), until the world closes."""
    taken = 0
    with DriverEndpoint(name, attach_timeout=20, spin=spin) as driver:
        action = driver.declaration.neutral_action()
        estimate = np.zeros(len(driver.declaration.estimate_names))
        while (msg := driver.wait_frame()) is not None:
            driver.send_action(msg.seq, action, estimate)
            taken += 1
    print(taken)
    return 0


def _spawn_driver(name: str, spin: float) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, __file__, "--driver", name, "--spin", repr(spin)],
                            stdout=subprocess.PIPE, text=True)


def _frames(decl, rng=None) -> tuple:
    if rng is None:
        return tuple(np.zeros(c.shape, dtype=np.uint8) for c in decl.cameras)
    return tuple(rng.integers(0, 256, c.shape, dtype=np.uint8) for c in decl.cameras)


def bench_lockstep(trips: int, warmup: int, decl, spin: float) -> dict:
    name = f"bench-bridge-{os.getpid()}"
    frame = _frames(decl, np.random.default_rng(0))
    truth = np.zeros(len(decl.truth))
    lat = np.empty(trips, dtype=np.int64)
    clock = time.perf_counter_ns
    with WorldEndpoint(name, decl, lockstep=True, spin=spin) as world:
        proc = _spawn_driver(name, spin)
        try:
            world.wait_for_driver(timeout=30)
            for _ in range(warmup):
                world.wait_action(world.publish(frame, truth), timeout=10)
            start = clock()
            for i in range(trips):
                frame[0][0, 0, 0] = i & 0xFF
                t0 = clock()
                seq = world.publish(frame, truth)
                act = world.wait_action(seq, timeout=10)
                lat[i] = clock() - t0
                assert act.seq == seq
            elapsed = (clock() - start) / 1e9
        finally:
            world.close()
            proc.communicate(timeout=10)
    us = lat / 1e3
    return {"trips": trips, "world": decl.name, "images": [list(c.shape) for c in decl.cameras],
            "median_us": float(np.median(us)),
            "p90_us": float(np.percentile(us, 90)), "p99_us": float(np.percentile(us, 99)),
            "max_us": float(us.max()), "mean_us": float(us.mean()), "round_trips_per_s": trips / elapsed}


def bench_free_running(seconds: float, decl, spin: float) -> dict:
    name = f"bench-bridge-free-{os.getpid()}"
    frame = _frames(decl)
    truth = np.zeros(len(decl.truth))
    with WorldEndpoint(name, decl, lockstep=False, spin=spin) as world:
        proc = _spawn_driver(name, spin)
        try:
            world.wait_for_driver(timeout=30)
            start = time.perf_counter()
            seq0 = world.seq
            while time.perf_counter() - start < seconds:
                frame[0][0, 0, 0] = world.seq & 0xFF
                world.publish(frame, truth)
                world.latest_action()
            elapsed = time.perf_counter() - start
            published = world.seq - seq0
        finally:
            world.close()
            out, _ = proc.communicate(timeout=10)
    taken = int(out.strip() or 0)
    return {"seconds": elapsed, "published": published, "published_per_s": published / elapsed,
            "taken": taken, "taken_per_s": taken / elapsed}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trips", type=int, default=5000, help="measured lock-step round trips (default 5000)")
    ap.add_argument("--warmup", type=int, default=500, help="unmeasured round trips first (default 500)")
    ap.add_argument("--world", default="highway", help="highway (one camera) or sidewalk (stereo pair)")
    ap.add_argument("--spin", type=float, default=100e-6, help="busy-wait before a futex sleep [s] (100e-6)")
    ap.add_argument("--free-seconds", type=float, default=1.0, help="duration of the free-running run [s]")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    ap.add_argument("--driver", metavar="NAME", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.driver:
        return run_driver(args.driver, args.spin)

    decl = worlds.get(args.world)
    lock = bench_lockstep(args.trips, args.warmup, decl, args.spin)
    images = " + ".join(f"{c.width}x{c.height}x{c.channels}" for c in decl.cameras)
    print(f"lock-step round trip, {decl.name} ({images} + truth -> driver process -> action), "
          f"{lock['trips']} trips, spin {args.spin * 1e6:g} us:")
    print(f"  median {lock['median_us']:.1f} us   p90 {lock['p90_us']:.1f} us   p99 {lock['p99_us']:.1f} us   "
          f"max {lock['max_us']:.1f} us   mean {lock['mean_us']:.1f} us")
    print(f"  {lock['round_trips_per_s']:.0f} frames/s (round trips per second)")
    free = None
    if args.free_seconds > 0:
        free = bench_free_running(args.free_seconds, decl, args.spin)
        print(f"free-running, {free['seconds']:.1f} s: the world published {free['published_per_s']:.0f} frames/s "
              f"without waiting; the driver took {free['taken_per_s']:.0f} frames/s (always the newest)")
    if args.json:
        args.json.write_text(json.dumps({"lockstep": lock, "free_running": free, "cpus": os.cpu_count()},
                                        indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
