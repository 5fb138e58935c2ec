"""The data-collection expert: the Chen controller on the true indicators, with seeded perturbations.

DeepDriving's data came from 12 hours of human driving; the controller alone keeps to lane centres and would
never show a network a car astride a marking or turned across its lane. So the expert, from the episode's
seed, mixes the controller's own driving with:
- a cruise speed drawn per episode (it closes in on some cars and is passed by others);
- correlated steering noise for stretches of time;
- forced lane changes left and right, when the target lane exists and is free ahead;
- wandering: for a few seconds it steers after a target lateral offset that drifts across the whole road and
  its verges (an Ornstein-Uhlenbeck process), so every lateral position, the on-marking band and the overlap
  are covered as much as the lane centres;
- drifts: a held steering bias for up to two seconds, then the controller recovers (angles to about 0.4 rad).
The expert sees the true lateral offset `d` besides the indicators (it is the privileged teacher). The label
of each frame names the perturbation acting on it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from controller.highway.chen import KEEP, ChenController, ChenParams
from core.worlds.highway import INDEX, NEIGHBOUR_LANE, STEER_LOCK_RAD, Action

PERTURBATIONS = ("none", "noise", "wander", "drift", "recovery", "forced-change")


@dataclass(frozen=True)
class PerturbationConfig:
    cruise: tuple = (14.0, 24.0)        # [m/s] the episode's cruise speed is drawn from this range
    noise_std: float = 0.04             # [-] steering noise standard deviation while noise is on
    noise_tau: float = 1.0              # [s] correlation time of the noise
    noise_on: float = 6.0               # [s] mean length of a noisy stretch
    noise_off: float = 12.0             # [s] mean length of a quiet stretch
    change_every: float = 12.0          # [s] mean time between forced lane changes
    change_clear: float = 15.0          # [m] a forced change needs the target lane free this far ahead
    wander_every: float = 5.0           # [s] mean time between wanders
    wander_time: tuple = (3.0, 10.0)    # [s] how long a wander lasts
    wander_tau: float = 2.0             # [s] how fast the target offset moves (OU correlation time)
    wander_outside: float = 1.2         # [m] the target may go this far beyond the road edges
    drift_every: float = 12.0           # [s] mean time between drifts
    drift_steer: tuple = (0.03, 0.3)    # [-] magnitude of the steering bias of a drift
    drift_time: tuple = (0.4, 2.0)      # [s] how long a drift lasts
    recovery_time: float = 3.0          # [s] frames after a drift or a wander are labelled "recovery"


class PerturbedExpert:
    def __init__(self, lanes: int, lane_width: float, seed: int, config: PerturbationConfig = PerturbationConfig(),
                 dt: float = 0.1):
        self.rng = np.random.default_rng([int(seed), 0xE4])
        self.config, self.dt = config, dt
        self.half_width = lanes * lane_width / 2  # [m] centreline to a road edge
        self.cruise = float(self.rng.uniform(*config.cruise))
        self.controller = ChenController(lanes, replace(ChenParams(), v_cruise=self.cruise))
        self._noise = 0.0
        self._noise_on = False
        self._drift_left = 0          # steps of drift still to go
        self._drift_bias = 0.0
        self._wander_left = 0         # steps of wander still to go
        self._wander_target = 0.0     # [m] the lateral offset the wander steers after
        self._recovery_left = 0

    def _chance(self, mean_interval: float) -> bool:
        """A Poisson event with the given mean interval [s] happens in this step."""
        return self.rng.uniform() < self.dt / mean_interval

    def _maybe_force_change(self, v: np.ndarray) -> None:
        c = self.config
        if self.controller.state != KEEP or not self._chance(c.change_every):
            return
        options = []
        if v[INDEX["toMarking_LL"]] > -NEIGHBOUR_LANE and v[INDEX["dist_LL"]] > c.change_clear:
            options.append("left")
        if v[INDEX["toMarking_RR"]] < NEIGHBOUR_LANE and v[INDEX["dist_RR"]] > c.change_clear:
            options.append("right")
        if options:
            self.controller.begin_lane_change(options[int(self.rng.integers(len(options)))])

    def _wander_steer(self, angle: float, d: float) -> float:
        """Steer after the wandering target offset (an Ornstein-Uhlenbeck walk over the road and verges)."""
        c = self.config
        limit = self.half_width + c.wander_outside
        a = math.exp(-self.dt / c.wander_tau)
        self._wander_target = a * self._wander_target + math.sqrt(1 - a * a) * limit * 0.7 * \
            float(self.rng.standard_normal())
        self._wander_target = float(np.clip(self._wander_target, -limit, limit))
        # the Chen controller's lane-keeping law, aimed at the target instead of the lane centre
        return (angle - (d - self._wander_target) / 8.0) / STEER_LOCK_RAD / 1.5

    def act(self, indicators, speed: float, d: float) -> tuple[Action, str]:
        """The command for this 10 Hz frame and the name of the perturbation acting on it.

        indicators: the true 14; speed [m/s]; d: the true lateral offset [m] (positive left)."""
        c = self.config
        v = np.asarray(indicators, dtype=np.float64)
        if self._wander_left == 0 and self._drift_left == 0:
            self._maybe_force_change(v)
        action = self.controller.act(v, speed)  # always run: its timers and history stay current
        label = "forced-change" if self.controller.state != KEEP else "none"
        steer = action.steer

        if self._wander_left == 0 and self._drift_left == 0 and label == "none":
            if self._chance(c.wander_every):
                self._wander_left = max(1, round(self.rng.uniform(*c.wander_time) / self.dt))
                self._wander_target = d
            elif self._chance(c.drift_every):
                self._drift_left = max(1, round(self.rng.uniform(*c.drift_time) / self.dt))
                self._drift_bias = float(self.rng.uniform(*c.drift_steer) * self.rng.choice([-1.0, 1.0]))

        # correlated steering noise, switched on and off in stretches
        if self._chance(c.noise_off if not self._noise_on else c.noise_on):
            self._noise_on = not self._noise_on
        a = math.exp(-self.dt / c.noise_tau)
        self._noise = a * self._noise + math.sqrt(1 - a * a) * c.noise_std * float(self.rng.standard_normal())

        if self._wander_left > 0:
            steer = self._wander_steer(v[INDEX["angle"]], d)
            self._wander_left -= 1
            self._recovery_left = round(c.recovery_time / self.dt)
            label = "wander"
        elif self._drift_left > 0:
            steer = action.steer + self._drift_bias
            self._drift_left -= 1
            self._recovery_left = round(c.recovery_time / self.dt)
            label = "drift"
        elif self._recovery_left > 0:
            self._recovery_left -= 1
            label = "recovery" if label == "none" else label
        if self._noise_on:
            steer += self._noise
            label = "noise" if label == "none" else label
        return Action(float(np.clip(steer, -1.0, 1.0)), action.accel, action.brake), label
