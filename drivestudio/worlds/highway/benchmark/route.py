"""One route driven by one model: the same loop as `drive` (drivestudio/loop.py's run_loop), in process or with
the driver in its own process over the bridge, with the benchmark's metrics and crash clips.

What a route measures comes from the truth only, so it is the same whatever drives: the highway's metrics
(controller/highway/metrics.py: collisions, off-road events, overtakes, distance) plus the lateral offset from the
lane centre and the time on markings outside lane changes (RouteMetrics below, which holds the highway's metrics).
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from controller.highway.metrics import HighwayMetrics
from core.children import popen
from core.conditions import SEEDED
from core.worlds.highway import lane_centres
from drivestudio.errors import RunError
from drivestudio.loop import in_process, run_loop
from drivestudio.worlds.highway.benchmark.models import ModelSpec
from drivestudio.worlds.highway.benchmark.suite import Route
from sim.camera import DEFAULT_RENDERER
from sim.highway.config import WorldConfig

BLOCKED_SECONDS = 60.0    # [s] a host car that drove less than BLOCKED_METRES in this long is blocked ...
BLOCKED_METRES = 10.0     # [m] ... and its route ends (CARLA ends a route whose agent is blocked, too)
CHANGE_MARGIN = 2.0       # [s] before and after a marking crossing that ends in another lane: part of the change
PROGRESS_EVERY = 50       # steps between progress reports
SHM_PREFIX = "drivestudio-"


@dataclass(frozen=True)
class RunOptions:
    transport: str = "in-process"    # or "shm"
    device: str = "cpu"
    renderer: str = DEFAULT_RENDERER
    condition: str = SEEDED          # the named condition(s) of the routes' frames: each route's seed draws one
    clips: int = 10                  # clips kept per route (0: none)
    clip_before: float = 5.0         # [s] of the clip before the event
    clip_after: float = 1.0          # [s] after it


# --- metrics ---------------------------------------------------------------------------------------------------
class RouteMetrics:
    """The highway's metrics (`base`: controller/highway/metrics.py's HighwayMetrics, as `drive` reports them) and
    what only the benchmark reports, per step from the truth: the host car's offset from its lane centre, its lane
    and whether it is on a marking; `report` is the base's report and then these columns, lane changes split from
    the rest."""

    def __init__(self, world, base):
        self.base = base
        self.dt = world.dt
        self._offset: list[float] = []
        self._lane: list[int] = []
        self._marking: list[bool] = []

    def observe(self, obs) -> None:
        self.base.observe(obs)
        t = obs.truth
        centre = lane_centres(t.lanes, t.lane_width)[t.lanes_left]
        self._offset.append(float(t.ego[4]) - float(centre))
        self._lane.append(int(t.lanes_left))
        self._marking.append(bool(t.on_marking))

    def add_time(self, stage: str, seconds: float) -> None:
        self.base.add_time(stage, seconds)

    def table(self) -> str:
        return self.base.table()

    @property
    def wall_time(self) -> float:
        return self.base.wall_time

    @wall_time.setter
    def wall_time(self, value: float) -> None:
        self.base.wall_time = value

    def lane_change_mask(self) -> np.ndarray:
        """Steps that belong to a lane change: every run of on-marking steps that the host car leaves in another
        lane than it entered from, widened by CHANGE_MARGIN either side (the pull-out and the settling)."""
        marking = np.asarray(self._marking, dtype=bool)
        lane = np.asarray(self._lane, dtype=np.int64)
        n = len(marking)
        mask = np.zeros(n, dtype=bool)
        margin = int(round(CHANGE_MARGIN / self.dt))
        edges = np.flatnonzero(np.diff(np.concatenate([[0], marking.astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):   # on-marking runs [a, b)
            entry = lane[a - 1] if a > 0 else lane[a]
            leave = lane[b] if b < n else lane[b - 1]
            if entry != leave:
                mask[max(0, a - margin):min(n, b + margin)] = True
        return mask

    def report(self) -> dict:
        r = self.base.report()
        offset = np.asarray(self._offset)
        marking = np.asarray(self._marking, dtype=bool)
        keep = ~self.lane_change_mask()
        n_keep = int(keep.sum())
        runs = np.flatnonzero(np.diff(np.concatenate([[0], (marking & keep).astype(np.int8), [0]])))
        return {**r, "lateral_rms_m": round(float(np.sqrt(np.mean(offset[keep] ** 2))), 4) if n_keep else 0.0,
                "lateral_steps": n_keep,
                "marking_time_s": round(float(np.sum(marking & keep)) * self.dt, 1),
                "marking_episodes": len(runs) // 2}


# --- the route as a world: blocked cars end it -------------------------------------------------------------------
class _Ended:
    """An observation after which the route cannot go on, and why."""

    def __init__(self, obs, reason: str):
        self._obs, self.end = obs, reason

    def __getattr__(self, name):
        return getattr(self._obs, name)


class RouteWorld:
    """The world as run_loop sees it on a route: as it is, except that a blocked host car ends the route."""

    def __init__(self, world):
        self.world = world
        self.dt = world.dt
        self.declaration = world.declaration
        self._moved: deque = deque(maxlen=int(round(BLOCKED_SECONDS / world.dt)))

    @property
    def timings(self) -> dict[str, float]:
        return self.world.timings

    @timings.setter
    def timings(self, value: dict[str, float]) -> None:
        self.world.timings = value

    def observe(self, render=None):
        return self.world.observe(render)

    def step(self, action, render=None):
        obs = self.world.step(action, render)
        self._moved.append(float(obs.truth.speed) * self.dt)
        if len(self._moved) == self._moved.maxlen and sum(self._moved) < BLOCKED_METRES:
            return _Ended(obs, "blocked")
        return obs

    def recover(self) -> None:
        self.world.recover()

    def close(self) -> None:
        self.world.close()


def world_for(route: Route, renderer: str = DEFAULT_RENDERER, inset: str = "", condition: str = SEEDED):
    """The route's world: the highway's configuration (its defaults, as `drive` has them) of the route's track,
    lanes, seed, cars and start lane, with the inset (the rear-view mirror, the side views) of a model that learned
    one, drawn in `condition` (a mix: the route's seed draws one)."""
    from sim.highway.world import World  # lazy: pybullet and SUMO, only in a route's process
    from sim.mirror import inset_options  # lazy: with the world
    return World(WorldConfig(track=route.track_ref or route.track, lanes=route.lanes, seed=route.seed,
                             cars=route.cars, renderer=renderer, start_lane=route.start_lane,
                             scenario=route.scenario or None, condition=condition, **inset_options(inset)))


# --- drivers --------------------------------------------------------------------------------------------------
_PREDICTORS: dict = {}


def driver_for(model: ModelSpec, device: str):
    """The driver `drive --model` makes (the highway plugin's); a worker keeps each checkpoint's predictor for its
    next routes."""
    from drivestudio import worlds  # lazy: the plugin registry loads the worlds, only in a route's process
    from drivestudio.worlds.highway.drivers import chen_driver  # lazy: the controllers, only in a route's process
    plugin: Any = worlds.get("highway")
    if model.path is None or model.policy:
        return plugin.driver(model.driver, device)
    key = (model.path, device)
    if key not in _PREDICTORS:
        from drivestudio.checkpoints import load_predictor_for  # lazy: as the drivers, only in a route's process
        _PREDICTORS[key] = load_predictor_for(model.path, "highway", device)
    return chen_driver(model.driver, _PREDICTORS[key])


def _driver_command(name: str, model: ModelSpec, device: str) -> list[str]:
    return [sys.executable, "-m", "drivestudio", "drive", "--shm", name, "--model", str(model.driver),
            "--device", device]


# --- one route --------------------------------------------------------------------------------------------------
_runs = iter(range(1 << 30))


def run_route(route: Route, model: ModelSpec, opts: RunOptions, clip_dir: Path | None = None,
              progress=None) -> dict:
    """Drive `route` with `model`; returns the route's metrics, how it ended and its clips."""
    from drivestudio.worlds.highway.benchmark.clips import (
        ClipRecorder,  # lazy: OpenCV video writing, only in a route's process
    )

    world = world_for(route, opts.renderer, model.inset, opts.condition)
    t0 = time.perf_counter()
    try:
        metrics = RouteMetrics(world, HighwayMetrics.of(world))
        recorder = ClipRecorder(world, route, model, clip_dir, opts if clip_dir is not None else
                                RunOptions(clips=0))
        steps = [0]

        def on_step(rec) -> None:
            recorder(rec)
            steps[0] += 1
            if progress is not None and steps[0] % PROGRESS_EVERY == 0:
                progress(PROGRESS_EVERY * world.dt)

        route_world = RouteWorld(world)
        if opts.transport == "shm":
            last, driver_timings = _run_over_bridge(route_world, world, model, opts, route.seconds, metrics,
                                                    on_step)
        else:
            driver = driver_for(model, opts.device)
            last = run_loop(route_world, in_process(driver), route.seconds, render=True, metrics=metrics,
                            on_step=on_step)
            driver_timings = dict(driver.timings)
        for stage, seconds in driver_timings.items():
            metrics.add_time(stage, seconds)
        end = last.end or "finished"
        clips = recorder.finish(last)
        report = metrics.report()
        scenario = world.scenario_report()
    finally:
        world.close()
    if progress is not None:   # what was not reported yet: the last steps, and the rest of a route that ended early
        progress(route.seconds - (steps[0] // PROGRESS_EVERY) * PROGRESS_EVERY * world.dt)
    return {"route": route.name, "model": model.key, "condition": world.condition, "end": end, "seconds": route.seconds,
            "driven_s": round(report["simulated_time_s"], 3), "metrics": report, "clips": clips,
            "clips_skipped": recorder.skipped, "wall_s": round(time.perf_counter() - t0, 2),
            "controller_agreed": recorder.agreed, "scenario": scenario}


def _run_over_bridge(route_world, world, model: ModelSpec, opts: RunOptions, seconds: float, metrics, on_step):
    """The world here, the driver in a `drivestudio drive --shm` process, in lock-step (drive without
    --in-process)."""
    from drivestudio.bridge_loop import ShmExchange  # lazy: the bridge, only for --shm
    from drivestudio.drive_session import _wait_for_driver  # lazy: the bridge, only for --shm
    from shm_bridge.endpoints import WorldEndpoint  # lazy: the bridge, only for --shm

    name = f"{SHM_PREFIX}{os.getpid()}-b{next(_runs)}"
    log = tempfile.TemporaryFile()
    stats = Path(tempfile.gettempdir()) / f".{name}.json"
    cmd = _driver_command(name, model, opts.device) + ["--stats-out", str(stats)]
    reason = "error"
    with WorldEndpoint(name, world.declaration, lockstep=True) as ep:
        proc = popen(cmd, signal.SIGTERM, stdout=subprocess.DEVNULL, stderr=log)   # ends with this worker
        try:
            _wait_for_driver(ep, 120.0, proc)
            exchange = ShmExchange(ep)
            last = run_loop(route_world, exchange, seconds, render=True, metrics=metrics, on_step=on_step)
            reason = "host lost" if last.end == "host lost" else "finished"   # a blocked car's route is over too
        except Exception as e:
            log.seek(0)
            tail = [ln for ln in log.read().decode(errors="replace").splitlines() if ln.strip()][-1:]
            raise RunError(f"{e}{' (driver: ' + tail[0] + ')' if tail else ''}") from None
        finally:
            ep.end(reason)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            log.close()
            timings = _take_stats(stats)   # also when the run was cut short: nothing stays in the temp folder
    metrics.add_time("transfer", max(0.0, exchange.round_trip - sum(timings.values())))
    return last, timings


def _take_stats(path: Path) -> dict:
    """The driver's timings from its statistics file, which is removed (empty when it wrote none)."""
    try:
        return json.loads(path.read_text()).get("timings", {})
    except (OSError, ValueError):
        return {}
    finally:
        path.unlink(missing_ok=True)


def completion(result: dict) -> float:
    """Route completion: the share of the route's simulated time driven before it ended."""
    if result["end"] == "finished":
        return 1.0
    return min(1.0, result["driven_s"] / result["seconds"]) if result["seconds"] else 0.0

