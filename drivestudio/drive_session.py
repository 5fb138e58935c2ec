"""Closed-loop driving sessions: the world side, the driver side, both at once over the bridge, or in one
process. Each ends with the metrics table printed and saved as JSON (controller/metrics.py)."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

from controller.metrics import ClosedLoopMetrics
from shm_bridge.endpoints import BridgeTimeout, DriverEndpoint, WorldEndpoint
from shm_bridge.signals import exit_on_sigterm
from sim.world import World, WorldConfig

from .bridge_loop import ShmExchange, serve_driver
from .errors import UsageError
from .loop import Driver, in_process, run_loop
from .outputs import VideoWriter, write_json, write_text
from .overlays import overlay_observation

ATTACH_SLICE = 0.25  # [s] while waiting for a driver we started, check it is still alive this often


class _Recorder:
    """drive --record: every step's overlay (truth and the driver's estimate) into an mp4."""

    def __init__(self, path: str | None, world: World, label: str):
        self.writer = VideoWriter(path) if path else None
        self.world, self.label = world, label

    def __call__(self, rec) -> None:
        if self.writer is not None:
            t = rec.obs.truth
            title = f"t {rec.obs.t:5.1f} s  {self.world.track.name}, {t.lanes} lanes, {t.speed:4.1f} m/s"
            estimate = None if self.label == "oracle" else rec.estimate
            self.writer.write(overlay_observation(rec.obs, estimate, self.world.track, title, label=self.label))

    def close(self, ok: bool) -> None:
        if self.writer is not None:
            (self.writer.close if ok else self.writer.abort)()
            if ok:
                print(f"recorded {self.writer.frames} overlays to {self.writer.path}")


def _finish(metrics: ClosedLoopMetrics, out: Path, extra: dict) -> None:
    report = {**metrics.report(), **extra}
    write_json(out / "metrics.json", report)
    table = metrics.table()
    write_text(out / "metrics.md", table + "\n")
    print(table)
    print(f"metrics saved in {out}/metrics.json")


def _wait_for_driver(ep: WorldEndpoint, timeout: float, proc: subprocess.Popen | None) -> None:
    t0 = time.monotonic()
    while True:
        try:
            ep.wait_for_driver(timeout=ATTACH_SLICE if proc is not None else timeout)
            return
        except BridgeTimeout:
            if proc is not None and proc.poll() is not None:
                raise UsageError(f"the driver process exited (status {proc.returncode}) before attaching") from None
            if proc is None or time.monotonic() - t0 > timeout:
                raise BridgeTimeout(f"no driver attached to '{ep.name}' within {timeout:.0f} s") from None


def run_world_side(args, cfg: WorldConfig, out: Path, driver_proc: subprocess.Popen | None = None,
                   driver_stats: Path | None = None) -> int:
    seconds = args.seconds if args.seconds is not None else math.inf
    metrics = None
    exchange = None
    with exit_on_sigterm(), World(cfg) as world:
        metrics = ClosedLoopMetrics(world.track.length, cfg.dt)
        with WorldEndpoint(args.shm, cfg.camera.height, cfg.camera.width, lockstep=not args.free_running) as ep:
            print(f"world on shared memory '{args.shm}' ({'free-running' if args.free_running else 'lock-step'}); "
                  f"waiting for a driver", file=sys.stderr, flush=True)
            _wait_for_driver(ep, getattr(args, "wait", 120.0), driver_proc)
            exchange = ShmExchange(ep)
            recorder = _Recorder(getattr(args, "record", None), world, getattr(args, "model", "driver"))
            ok = False
            try:
                run_loop(world, exchange, seconds, render=True, metrics=metrics, realtime=args.realtime,
                         on_step=recorder)
                ok = True
            except KeyboardInterrupt:
                if args.seconds is not None:
                    raise  # a bounded run was cut short
                ok = True
            finally:
                recorder.close(ok)
    extra = {"transport": "shared memory", "lockstep": not args.free_running, "driver": args.model
             if hasattr(args, "model") else "external", "track": world.track.name, "lanes": world.track.lanes,
             "cars": cfg.cars}
    driver_time = 0.0
    if driver_proc is not None:
        driver_proc.wait(timeout=15)
        if driver_stats is not None and driver_stats.exists():
            stats = json.loads(driver_stats.read_text())
            metrics.add_time("perception", stats["perception"])
            metrics.add_time("control", stats["control"])
            driver_time = stats["perception"] + stats["control"]
    metrics.add_time("transfer", max(0.0, exchange.round_trip - driver_time))
    _finish(metrics, out, extra)
    return 0


def run_driver_side(name: str, perception, stats_out: str | None) -> int:
    driver = Driver(perception)
    with exit_on_sigterm(), DriverEndpoint(name, attach_timeout=30.0) as ep:
        n = serve_driver(ep, driver)
    if stats_out:
        write_json(Path(stats_out), {"frames": n, **driver.timings})
    return 0


def run_both_sides(args, cfg: WorldConfig, out: Path) -> int:
    args.shm = f"drivestudio-{os.getpid()}"
    stats = out / "driver-timings.json"
    cmd = [sys.executable, "-m", "drivestudio", "drive", "--shm", args.shm, "--model", args.model,
           "--device", args.device, "--stats-out", str(stats)]
    proc = subprocess.Popen(cmd)
    try:
        return run_world_side(args, cfg, out, driver_proc=proc, driver_stats=stats)
    finally:
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def run_in_process(args, cfg: WorldConfig, perception, out: Path) -> int:
    driver = Driver(perception)
    with exit_on_sigterm(), World(cfg) as world:
        metrics = ClosedLoopMetrics(world.track.length, cfg.dt)
        recorder = _Recorder(args.record, world, args.model if args.model == "oracle" else driver.name)
        ok = False
        try:
            run_loop(world, in_process(driver), args.seconds, render=cfg.render, metrics=metrics,
                     realtime=args.realtime, on_step=recorder)
            ok = True
        finally:
            recorder.close(ok)
        extra = {"transport": "in process", "driver": args.model, "track": world.track.name,
                 "lanes": world.track.lanes, "cars": cfg.cars}
    for stage, seconds in driver.timings.items():
        metrics.add_time(stage, seconds)
    _finish(metrics, out, extra)
    return 0
