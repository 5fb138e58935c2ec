"""The one loop of docs/architecture.md, and its two transports, for any declared world.

    world.step(action) -> observation -> [transport] -> driver: perception(frames) -> controller -> action

`run_loop` is the world side and the only place a world is stepped by a driver. A transport is a function
`exchange(observation) -> (action, estimate)`: `in_process(driver)` calls the driver directly (dataset
generation, tests, Gymnasium users); the shared-memory transport (drivestudio/bridge_loop.py) hands the frame to a
driver in another process, as TORCS and Caffe did.

What the loop needs of a world: `dt` [s], `step(action, render) -> observation`, `observe(render)`, `timings`
(seconds per stage) and, for when_lost="recover", `recover()`. Of an observation: `frames` (one image per camera,
or None when not rendered), `record` (the truth record, declaration order), `t` and `end` (None, or why the
episode cannot go on). Of a driver: `act(percept) -> (action, estimate)`, where a percept has the observation's
`frames`, `record` and `t` (a bridge FrameMsg has them too), and `name`.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from core.signals import check as check_signals

Exchange = Callable[[object], tuple[np.ndarray, np.ndarray]]


def in_process(driver) -> Exchange:
    """The fast path: the driver runs in the world's process."""
    return driver.act


@dataclass
class StepRecord:
    """What one step of the loop saw and did, for recorders and overlays."""

    obs: object
    action: np.ndarray
    estimate: np.ndarray


def run_loop(world, exchange: Exchange, seconds: float, render: bool = True, metrics=None, realtime: bool = False,
             on_step: Callable[[StepRecord], None] | None = None, when_lost: str = "stop"):
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


def timed(driver, stage: str, fn, *args):
    """Call fn(*args), adding the seconds it took to driver.timings[stage]."""
    t0 = time.perf_counter()
    out = fn(*args)
    driver.timings[stage] = driver.timings.get(stage, 0.0) + time.perf_counter() - t0
    return out
