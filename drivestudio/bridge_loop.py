"""The loop's second transport: the world and the driver in separate processes over shared memory.

World side: `ShmExchange(endpoint)` plugs into drivestudio.loop.run_loop like `in_process(driver)` does, so there
is still one loop. Driver side: `serve_driver(endpoint, driver)` answers frames until the world ends the run. The
world honours the driver's flags: while `paused` it does not advance; in "manual" mode (an expert drives, as a
human did in TORCS) or under a world's correction rule, the world's supervisor decides what is applied, and the
driver's estimate is only recorded.
"""
from __future__ import annotations

import time

import numpy as np

from drivestudio.loop import Driver, Exchange, Observation, Supervisor, World
from shm_bridge.endpoints import DriverEndpoint, WorldEndpoint

PAUSE_POLL = 0.05  # [s] a paused world checks the flag this often (not latency-critical)


class ShmExchange:
    """World side of the bridge as a loop transport; `round_trip` sums the time spent waiting for the driver.

    supervisor(obs, action, driver_mode) -> (applied action, operation mode), or None: the driver's action is
    applied as it is. `operation` holds the operation mode of the last step."""

    def __init__(self, endpoint: WorldEndpoint, supervisor: Supervisor | None = None, world: World | None = None):
        self.endpoint = endpoint
        self.supervisor = supervisor
        self.world = world
        self.round_trip = 0.0
        self.operation = "network"
        decl = endpoint.declaration
        self._last = decl.neutral_action()
        self._no_estimate = np.full(len(decl.estimate_names), np.nan)
        self._mode: str | None = None
        # a declaration with modes names the truth field that holds the mode (WorldDeclaration checks it)
        self._mode_index = decl.index(decl.mode_field) if decl.modes and decl.mode_field else None

    def _follow_mode(self, obs: Observation, mode_index: int) -> None:
        """The behavioural mode is a shared flag: the world's own mode is announced before the first frame; when
        a driver changes the flag, the world switches at this step."""
        ep = self.endpoint
        if self._mode is None:
            self._mode = ep.declaration.modes[int(obs.record[mode_index])]
            ep.behaviour = self._mode
            return
        flag = ep.behaviour
        if flag != self._mode and flag in ep.declaration.modes:
            self._mode = flag
            if self.world is not None and hasattr(self.world, "set_mode"):
                self.world.set_mode(flag)
                obs.record[mode_index] = ep.declaration.modes.index(flag)

    def __call__(self, obs: Observation) -> tuple[np.ndarray, np.ndarray]:
        ep = self.endpoint
        while ep.paused:
            time.sleep(PAUSE_POLL)
        if self._mode_index is not None:
            self._follow_mode(obs, self._mode_index)
        t0 = time.perf_counter()
        seq = ep.publish(obs.frames, obs.record, obs.t)
        msg = ep.wait_action(seq) if ep.lockstep else ep.latest_action()
        self.round_trip += time.perf_counter() - t0
        if msg is None:  # free-running, no action yet: keep the last command (the neutral one at first)
            return self._last, self._no_estimate
        action = msg.action
        if self.supervisor is not None:
            action, self.operation = self.supervisor(obs, action, ep.driver_mode)
        self._last = action
        return action, msg.estimate


def serve_driver(endpoint: DriverEndpoint, driver: Driver) -> int:
    """Answer frames until the world closes the run; returns the number of frames answered."""
    n = 0
    while (msg := endpoint.wait_frame()) is not None:
        action, estimate = driver.act(msg)
        endpoint.send_action(msg.seq, action, estimate)
        n += 1
    return n


def supervised(exchange: Exchange, supervisor: Supervisor | None) -> Exchange:
    """An in-process transport with the world side's supervisor (manual mode, correction) applied, as ShmExchange
    applies it over the bridge."""
    if supervisor is None:
        return exchange

    def run(obs: Observation) -> tuple[np.ndarray, np.ndarray]:
        action, estimate = exchange(obs)
        applied, _ = supervisor(obs, action, "network")
        return applied, estimate
    return run
