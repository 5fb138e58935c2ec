"""The one loop of docs/architecture.md, and its two transports.

    world.step(action) -> observation -> [transport] -> driver: perception(frame) -> controller -> action

`run_loop` is the world side and the only place the world is stepped by a driver. A transport is a function
`exchange(observation) -> (action, estimate)`: `in_process(driver)` calls the driver directly (dataset
generation, tests, Gymnasium users); the shared-memory transport (drivestudio/bridge_loop.py) hands the
frame to a driver in another process, as TORCS and Caffe did.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from controller import ChenController
from controller.metrics import ClosedLoopMetrics
from shm_bridge.vocabulary import Action
from sim.world import Observation, World

Exchange = Callable[[Observation], tuple[Action, np.ndarray]]
Perception = Callable[[np.ndarray], np.ndarray]  # frame (h, w, 3) uint8 -> the 14 indicators


@dataclass
class Driver:
    """The driver side: perception (a model, or the ground truth itself for the oracle) and the Chen controller.

    `perception` maps a frame to the 14 indicators; None is the oracle (perfect perception: the upper bound
    every network is compared with). The controller is made on the first frame, when the lane count is known.
    """

    perception: Perception | None = None
    timings: dict = field(default_factory=lambda: {"perception": 0.0, "control": 0.0})
    controller: ChenController | None = None

    @property
    def name(self) -> str:
        return "oracle" if self.perception is None else getattr(self.perception, "name", "model")

    def act(self, frame: np.ndarray | None, truth: np.ndarray, speed: float, lanes: int) -> tuple[Action, np.ndarray]:
        """One frame: estimate the indicators, then the command. truth: the true 14 (used by the oracle only)."""
        t0 = time.perf_counter()
        estimate = np.asarray(truth, dtype=np.float64) if self.perception is None else \
            np.asarray(self.perception(frame), dtype=np.float64)
        t1 = time.perf_counter()
        if self.controller is None or self.controller.lanes != lanes:
            self.controller = ChenController(int(lanes))
        action = self.controller.act(estimate, speed)
        self.timings["perception"] += t1 - t0
        self.timings["control"] += time.perf_counter() - t1
        return action, estimate


def in_process(driver: Driver) -> Exchange:
    """The fast path: the driver runs in the world's process."""
    def exchange(obs: Observation) -> tuple[Action, np.ndarray]:
        t = obs.truth
        return driver.act(obs.frame, t.indicators, t.speed, t.lanes)
    return exchange


@dataclass
class StepRecord:
    """What one step of the loop saw and did, for recorders and overlays."""

    obs: Observation
    action: Action
    estimate: np.ndarray


def run_loop(world: World, exchange: Exchange, seconds: float, render: bool = True,
             metrics: ClosedLoopMetrics | None = None, realtime: bool = False,
             on_step: Callable[[StepRecord], None] | None = None, when_lost: str = "stop") -> Observation:
    """Drive `world` for `seconds` of simulated time (10 Hz steps; inf: until interrupted); returns the last
    observation.

    realtime paces the loop to wall-clock time; otherwise it runs as fast as it can. on_step sees every
    observation with the action taken on it (recording, video). If the host car gets lost off the road the
    run ends (when_lost="stop") or the car is put back on the nearest lane (when_lost="recover").
    """
    dt = world.config.dt
    steps = int(round(seconds / dt)) if seconds != float("inf") else None
    obs = world.observe(render)
    t_start = time.perf_counter()
    before = dict(world.timings)
    n = 0
    try:
        while steps is None or n < steps:
            action, estimate = exchange(obs)
            if on_step is not None:
                on_step(StepRecord(obs, action, estimate))
            obs = world.step(action, render)
            n += 1
            if metrics is not None:
                t = obs.truth
                gaps = world.track.gap(t.ego[3], t.cars[:, 3]) if len(t.cars) else np.zeros(0)
                metrics.update(t.speed, t.lanes_left, t.in_lane, obs.collision, obs.off_road, gaps)
            if realtime:
                ahead = n * dt - (time.perf_counter() - t_start)
                if ahead > 0:
                    time.sleep(ahead)
            if obs.lost:
                if when_lost == "stop":
                    break
                world.recover_ego()
                obs = world.observe(render)
    finally:  # an interrupted run still accounts for what it did
        if metrics is not None:
            metrics.wall_time += time.perf_counter() - t_start
            for stage in ("render", "physics", "traffic", "truth"):
                metrics.add_time(stage, world.timings[stage] - before[stage])
    return obs


def warm_up(world: World, seconds: float) -> Observation:
    """Let the traffic settle: the oracle drives the host car for `seconds`, nothing is rendered."""
    return run_loop(world, in_process(Driver()), seconds, render=False)
