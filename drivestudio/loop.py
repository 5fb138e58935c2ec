"""The one loop of docs/architecture.md, its two transports, and the contracts every world and driver keeps.

    world.step(action) -> observation -> [transport] -> driver: perception(frames) -> controller -> action

`run_loop` is the world side and the only place a world is stepped by a driver. A transport is an `Exchange`:
`in_process(driver)` calls the driver directly (dataset generation, tests, Gymnasium users); the shared-memory
transport (drivestudio/bridge_loop.py) hands the frame to a driver in another process, as TORCS and Caffe did.

The contracts are typing Protocols, so that a type checker holds both worlds (sim/highway/world.py,
sim/sidewalk/world.py), every driver and both transports to them: a method one world lacks is an error before it
is a crash.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

import numpy as np

from core.declaration import WorldDeclaration
from core.signals import check as check_signals


class Percept(Protocol):
    """What a driver sees of one step: an Observation, or the bridge's FrameMsg on the driver's side."""

    @property
    def frames(self) -> tuple: ...           # one uint8 RGB image per camera of the declaration (None: not rendered)

    @property
    def record(self) -> np.ndarray: ...      # the truth record, float64, in the declaration's order

    @property
    def t(self) -> float: ...                # [s] simulated time


class Observation(Percept, Protocol):
    """One step of a world as the loop sees it."""

    @property
    def end(self) -> str | None: ...         # why the episode cannot go on (the host car is lost), or None


class World(Protocol):
    """A declared world the loop can step (sim.highway.world.World, sim.sidewalk.world.SidewalkWorld)."""

    declaration: WorldDeclaration
    dt: float                                # [s] one step
    timings: dict[str, float]                # seconds spent per stage (render, physics, traffic, truth, ...)

    def observe(self, render: bool | None = None) -> Observation: ...

    def step(self, action, render: bool | None = None) -> Observation: ...

    def recover(self) -> None:
        """Put a lost host car back on the road (when_lost="recover")."""

    def close(self) -> None: ...


class Driver(Protocol):
    """Perception and control: a percept in, (action, estimate) out. The estimate has one value per name of the
    declaration's `estimate_names` (NaN where the driver has none)."""

    timings: dict[str, float]

    @property
    def name(self) -> str: ...              # what reports call it ("oracle", a checkpoint's description)

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]: ...


class Metrics(Protocol):
    """A world's closed-loop metrics (controller/*/metrics.py through the world's plugin)."""

    wall_time: float

    def observe(self, obs: Observation) -> None: ...

    def add_time(self, stage: str, seconds: float) -> None: ...

    def report(self) -> dict: ...

    def table(self) -> str: ...


# what the world side applies of a driver's command: (obs, action, driver_mode) -> (applied action, operation)
Supervisor = Callable[[Observation, np.ndarray, str], tuple[np.ndarray, str]]
Exchange = Callable[[Observation], tuple[np.ndarray, np.ndarray]]


def in_process(driver: Driver) -> Exchange:
    """The fast path: the driver runs in the world's process."""
    return driver.act


@dataclass
class StepRecord:
    """What one step of the loop saw and did, for recorders and overlays."""

    obs: Observation
    action: np.ndarray
    estimate: np.ndarray


def run_loop(world: World, exchange: Exchange, seconds: float, render: bool = True, metrics: Metrics | None = None,
             realtime: bool = False, on_step: Callable[[StepRecord], None] | None = None,
             when_lost: str = "stop") -> Observation:
    """Drive `world` for `seconds` of simulated time (inf: until interrupted); returns the last observation.

    realtime paces the loop to wall-clock time; otherwise it runs as fast as it can. on_step sees every
    observation with the action taken on it (recording, video). metrics.observe(obs) sees every new observation.
    If the episode cannot go on (the host car is lost), the run ends (when_lost="stop") or the world puts the
    host car back (when_lost="recover").
    """
    dt = world.dt
    steps = int(round(seconds / dt)) if seconds != float("inf") else None
    obs = world.observe(render)
    t_start = time.perf_counter()
    before = dict(world.timings)
    n = 0
    try:
        while steps is None or n < steps:
            check_signals()   # a SIGTERM whose exception a finaliser swallowed still ends the run
            action, estimate = exchange(obs)
            if on_step is not None:
                on_step(StepRecord(obs, action, estimate))
            obs = world.step(action, render)
            n += 1
            if metrics is not None:
                metrics.observe(obs)
            if realtime:
                ahead = n * dt - (time.perf_counter() - t_start)
                if ahead > 0:
                    time.sleep(ahead)
            if obs.end is not None:
                if when_lost == "stop":
                    break
                world.recover()
                obs = world.observe(render)
    finally:  # an interrupted run still accounts for what it did
        if metrics is not None:
            metrics.wall_time += time.perf_counter() - t_start
            for stage, total in world.timings.items():
                metrics.add_time(stage, total - before.get(stage, 0.0))
    return obs


T = TypeVar("T")


def timed(driver: Driver, stage: str, fn: Callable[..., T], *args: Any) -> T:
    """Call fn(*args), adding the seconds it took to driver.timings[stage]."""
    t0 = time.perf_counter()
    out = fn(*args)
    driver.timings[stage] = driver.timings.get(stage, 0.0) + time.perf_counter() - t0
    return out
