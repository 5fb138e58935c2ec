"""Closed-loop driving sessions for any world: the world side, the driver side, both at once over the bridge, or in
one process. A `Run` holds what a session needs: the world's configuration, the driver spec and how the run goes.
Each ends with the world's metrics table printed and saved as JSON, beside the run's resolved configuration."""
from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from core import worlds as declared
from core.children import end, popen
from core.settings import as_json
from core.signals import Terminated, exit_on_sigterm
from drivestudio import worlds
from drivestudio.bridge_loop import ShmExchange, serve_driver, supervised
from drivestudio.driver_spec import DriverSpec
from drivestudio.errors import RunError, UsageError
from drivestudio.loop import in_process, run_loop
from drivestudio.outputs import write_json, write_text
from shm_bridge.endpoints import BridgeTimeout, DriverEndpoint, PeerGone, WorldEndpoint, reclaim

ATTACH_SLICE = 0.25       # [s] while waiting for a driver we started, check it is still alive this often
DRIVER_ATTACH = 30.0      # [s] `drive --shm` waits this long for the world's segment
SHM_PREFIX = "drivestudio-"


@dataclass(frozen=True)
class View:
    """drive/serve --view: the run published to a web page (docs/studio.md)."""

    socket: Any                  # the bound listening socket
    host: str | None = None      # None: the loopback interface, no token
    control: bool = False        # the page may pause, resume and single-step
    fps: float = 10.0            # frames a second the page gets at most


@dataclass(frozen=True)
class Run:
    """A closed-loop run: the world (its Plugin and configuration), the driver (None: one that attaches over the
    bridge) and how the run goes."""

    plugin: Any
    config: Any
    driver: DriverSpec | None
    seconds: float | None = 60.0     # simulated seconds (None: until stopped)
    realtime: bool = False           # paced to wall-clock time
    free_running: bool = False       # the world never waits for the driver
    record: str | None = None        # a video of the run (.mp4)
    wait: float = 120.0              # [s] the world side waits this long for a driver
    device: str = "cpu"              # torch device of the driver
    shm: str | None = None           # the bridge's segment
    view: View | None = None

    @property
    def label(self) -> str:
        return str(self.driver) if self.driver is not None else "driver"

    def as_json(self) -> dict:
        """The resolved configuration, as `--config` reads it back."""
        return {"world": self.plugin.name, "settings": as_json(self.config),
                "model": None if self.driver is None else str(self.driver), "seconds": self.seconds,
                "realtime": self.realtime, "free_running": self.free_running, "device": self.device}


def _finish(metrics, out: Path, extra: dict, run: Run) -> None:
    report = {**metrics.report(), **extra}
    write_json(out / "config.json", run.as_json())
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
                raise RunError(f"the driver process exited (status {proc.returncode}) before attaching") from None
            if proc is None or time.monotonic() - t0 > timeout:
                raise BridgeTimeout(f"no driver attached to '{ep.name}' within {timeout:.0f} s") from None


def _open_view(run: Run, world, metrics):
    """drive/serve --view: the run's steps published to a web page (docs/studio.md), or None."""
    if run.view is None:
        return None
    from drivestudio.studio.view import RunView  # lazy: the web server only when asked for
    return RunView(run, world, metrics)


def _steps(*callbacks):
    """One step callback of several (None: absent)."""
    present = [c for c in callbacks if c is not None]

    def on_step(rec) -> None:
        for c in present:
            c(rec)
    return on_step


def _run_over_bridge(run: Run, world, metrics, ep, exchange, view, driver_proc):
    """The loop over the bridge, from waiting for the driver on; returns why the run ended (which the driver is
    told) and the signal that stopped it (None: none)."""
    reason, stopped = "finished", None
    recorder = run.plugin.recorder(world, run.record, run.label)
    seconds = run.seconds if run.seconds is not None else math.inf
    ok = False
    try:
        # the readiness line: from here a stop signal ends the run in order, its metrics saved
        print(f"world '{world.declaration.name}' on shared memory '{run.shm}' "
              f"({'free-running' if run.free_running else 'lock-step'}); waiting for a driver",
              file=sys.stderr, flush=True)
        _wait_for_driver(ep, run.wait, driver_proc)
        last = run_loop(world, exchange, seconds, render=True, metrics=metrics, realtime=run.realtime,
                        on_step=_steps(recorder, view))
        reason = "host lost" if last.end is not None else "finished"
        ok = True
    except PeerGone as gone:
        if not gone.finished:
            raise
        reason, ok = "driver finished", True
        print(str(gone), file=sys.stderr)
    except (KeyboardInterrupt, Terminated) as signal_:
        reason, stopped, ok = "interrupted", signal_, True   # what was driven until now is kept
    finally:
        recorder.close(ok)
        ep.end(reason if reason != "finished" or ok else "error")
    return reason, stopped


def run_world_side(run: Run, out: Path, driver_proc: subprocess.Popen | None = None,
                   driver_stats: Path | None = None) -> int:
    """The world over the bridge: publish, wait for the driver's action, step; the run's end is told to the driver
    (finished, host lost, interrupted, driver finished). Ctrl-C or SIGTERM, also while waiting for a driver, ends
    the run in order: metrics.json records "interrupted" and the signal is raised again afterwards (exit 128 + N)."""
    plugin = run.plugin
    exchange, reason, stopped = None, "finished", None
    with exit_on_sigterm(), plugin.world(replace(run.config, render=True)) as world:
        metrics = plugin.metrics(world)
        with WorldEndpoint(str(run.shm), world.declaration, lockstep=not run.free_running) as ep:
            exchange = ShmExchange(ep, plugin.supervisor(world, run.config, run.driver), world)
            view = _open_view(run, world, metrics)     # the page is there while the driver comes
            try:
                reason, stopped = _run_over_bridge(run, world, metrics, ep, exchange, view, driver_proc)
            finally:
                if view is not None:
                    view.close()
        extra = {"transport": "shared memory", "lockstep": not run.free_running, "driver": run.label,
                 "world": world.declaration.name, "end": reason,
                 **plugin.describe_run(world, run.config, run.driver)}
    driver_time = 0.0
    if driver_proc is not None:   # a driver still starting would wait for a world that is gone
        end(driver_proc, stopped, grace=5.0 if stopped is not None else 15.0)
        if driver_stats is not None and driver_stats.exists():
            stats = json.loads(driver_stats.read_text())
            for stage, value in stats.get("timings", {}).items():
                metrics.add_time(stage, value)
                driver_time += value
    metrics.add_time("transfer", max(0.0, exchange.round_trip - driver_time))
    _finish(metrics, out, extra, run)
    if stopped is not None:
        raise stopped   # the CLI says how the run ended, in one line, with status 128 + N
    return 0


def run_driver_side(name: str, model: str | None, device: str = "cpu", seed: int = 0,
                    attach_wait: float | None = None, stats_out: str | None = None) -> int:
    """The driver over the bridge: the world's declaration comes from the header; the driver spec `model` (default:
    the world's own driver) must fit it."""
    with exit_on_sigterm(), DriverEndpoint(name, attach_timeout=attach_wait or DRIVER_ATTACH) as ep:
        decl = ep.declaration
        try:
            plugin = worlds.get(decl.name)
        except UsageError:
            declared.register(decl)   # a world this installation does not know: drive it from its header
            plugin = worlds.Plugin.__new__(worlds.Plugin)
            plugin.declaration = decl
        spec = plugin.parse_driver(model or plugin.expert_names[0])
        driver = plugin.driver(spec, device, decl, seed)
        ep.require(world=decl.name, action=decl.action_names)
        n = serve_driver(ep, driver)
        print(f"drove {n} frames; the world ended the run: {ep.end_reason}", file=sys.stderr)
    if stats_out:
        write_json(Path(stats_out), {"frames": n, "timings": dict(getattr(driver, "timings", {}))})
    return 0


def run_both_sides(run: Run, out: Path) -> int:
    reclaim(SHM_PREFIX)   # segments of earlier runs killed with SIGKILL (world and driver both dead)
    run = replace(run, shm=f"{SHM_PREFIX}{os.getpid()}")
    stats = out / "driver-timings.json"
    cmd = [sys.executable, "-m", "drivestudio", "drive", "--shm", str(run.shm), "--model", str(run.driver),
           "--device", run.device, "--seed", str(run.config.seed), "--stats-out", str(stats)]
    proc = popen(cmd, signal.SIGTERM)   # ends with this process, however it ends, removing the segment then
    try:
        return run_world_side(run, out, driver_proc=proc, driver_stats=stats)
    finally:
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def run_in_process(run: Run, out: Path) -> int:
    plugin, spec = run.plugin, run.driver
    assert spec is not None
    render = plugin.needs_frames(spec, bool(run.record)) or run.view is not None
    seconds = run.seconds if run.seconds is not None else math.inf
    with exit_on_sigterm(), plugin.world(replace(run.config, render=render)) as world:
        driver = plugin.driver(spec, run.device, world.declaration, run.config.seed)
        metrics = plugin.metrics(world)
        recorder = plugin.recorder(world, run.record, run.label)
        view = _open_view(run, world, metrics)
        ok, end, stopped = False, "finished", None
        try:
            last = run_loop(world, supervised(in_process(driver), plugin.supervisor(world, run.config, spec)),
                            seconds, render=render, metrics=metrics, realtime=run.realtime,
                            on_step=_steps(recorder, view))
            end, ok = "host lost" if last.end is not None else "finished", True
        except (KeyboardInterrupt, Terminated) as signal_:   # as over the bridge: metrics of what was driven
            end, stopped, ok = "interrupted", signal_, True
        finally:
            recorder.close(ok)
            if view is not None:
                view.close()
        extra = {"transport": "in process", "driver": run.label, "world": world.declaration.name,
                 "end": end, **plugin.describe_run(world, run.config, spec)}
    for stage, spent in getattr(driver, "timings", {}).items():
        metrics.add_time(stage, spent)
    _finish(metrics, out, extra, run)
    if stopped is not None:
        raise stopped
    return 0
