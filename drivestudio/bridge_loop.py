"""The loop's second transport: the world and the driver in separate processes over shared memory.

World side: `shm_exchange(endpoint)` plugs into drivestudio.loop.run_loop like `in_process(driver)` does, so
there is still one loop. Driver side: `serve_driver(endpoint, driver)` answers frames until the world ends
the run. The world honours the driver's flags: while `paused` it does not advance; in "manual" mode (an
expert drives, as a human did in TORCS) the world-side oracle's command is applied and the network's estimate
only recorded.
"""
from __future__ import annotations

import time

import numpy as np

from shm_bridge.endpoints import DriverEndpoint, WorldEndpoint
from shm_bridge.layout import TRUTH_INDEX, pack_truth_arrays
from shm_bridge.vocabulary import Action
from sim.world import Observation

from .loop import Driver, Exchange

PAUSE_POLL = 0.05  # [s] a paused world checks the flag this often (not latency-critical)


def truth_record(obs: Observation) -> np.ndarray:
    t = obs.truth
    return pack_truth_arrays(t.indicators, t.ego, lanes_left=t.lanes_left, lanes=t.lanes, lane_width=t.lane_width,
                             speed=t.speed, in_lane=t.in_lane, on_marking=t.on_marking, t=obs.t,
                             collision=obs.collision, off_road=obs.off_road)


class ShmExchange:
    """World side of the bridge as a loop transport; `round_trip` sums the time spent waiting for the driver."""

    def __init__(self, endpoint: WorldEndpoint):
        self.endpoint = endpoint
        self.round_trip = 0.0
        self._expert = Driver()  # drives in "manual" mode
        self._last = Action()

    def __call__(self, obs: Observation) -> tuple[Action, np.ndarray]:
        ep = self.endpoint
        while ep.paused:
            time.sleep(PAUSE_POLL)
        t0 = time.perf_counter()
        seq = ep.publish(obs.frame, truth_record(obs))
        msg = ep.wait_action(seq) if ep.lockstep else ep.latest_action()
        self.round_trip += time.perf_counter() - t0
        if msg is None:  # free-running, no action yet: coast
            return self._last, obs.truth.indicators
        action = msg.action
        if ep.driver_mode == "manual":
            t = obs.truth
            action, _ = self._expert.act(obs.frame, t.indicators, t.speed, t.lanes)
        self._last = action
        return action, msg.estimate


def shm_exchange(endpoint: WorldEndpoint) -> Exchange:
    return ShmExchange(endpoint)


def serve_driver(endpoint: DriverEndpoint, driver: Driver) -> int:
    """Answer frames until the world closes the run; returns the number of frames answered."""
    n = 0
    while (msg := endpoint.wait_frame()) is not None:
        lanes = int(msg.truth[TRUTH_INDEX["lanes"]])
        action, estimate = driver.act(msg.frame, msg.indicators, msg.speed, lanes)
        endpoint.send_action(msg.seq, action, estimate)
        n += 1
    return n
