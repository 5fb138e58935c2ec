"""The expert with its steering knocked aside now and then: data that shows how to recover.

A scripted expert drives the middle of its course so steadily that its data never shows the car off that course,
heading away from it or late for an obstacle, and a network trained on that data has never seen the states its own
small errors lead to (the covariate shift of imitation learning). A human driver's data holds such recoveries by
nature; Chowdhuri, Pankaj and Zipser's RC cars were driven by people. The remedy here is the one of Codevilla et
al. (End-to-end driving via conditional imitation learning, ICRA 2018) and of DART (Laskey et al., 2017): now and
then a triangular impulse is added to the steering the car receives for a fraction of a second, the car swerves off
its course, and the expert brings it back. Every step's label is the expert's own command for the state the car is
in, during the impulse too (then it is the expert's counter-steering, the strongest recovery the data holds); only
the command applied carries the impulse.

Reads the truth record only; its randomness is a function of its seed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controller.sidewalk.experts import SidewalkExpert
from core.worlds.sidewalk import STEP


@dataclass(frozen=True)
class PerturbParams:
    every: tuple = (1.5, 4.0)        # [s] between the end of one impulse and the start of the next, uniform
    length: tuple = (0.5, 1.5)       # [s] an impulse's duration, uniform
    peak: tuple = (0.2, 0.5)         # steering units (0.5 is straight ahead): the impulse's height, uniform, either
                                     # sign; measured: the car up to 1.7 m off its course, 0.3 rad spread of heading


def triangle(t: float, length: float) -> float:
    """The impulse's shape at time t into it: 0 at both ends, 1 at the middle."""
    if not 0.0 <= t <= length:
        return 0.0
    return 1.0 - abs(2.0 * t / length - 1.0)


class PerturbedExpert:
    """act(record) -> (applied, expert): the expert's (steer, motor) for the record, and the command to apply: the
    same, or during an impulse its steering plus the impulse (clipped to the servo's range)."""

    def __init__(self, seed: int = 0, params: PerturbParams = PerturbParams(), dt: float = STEP):
        self.p, self.dt = params, dt
        self.rng = np.random.default_rng([int(seed), 0x9E27])
        self.expert = SidewalkExpert()
        self.wait = float(self.rng.uniform(*params.every))
        self.t, self.length, self.peak = 0.0, 0.0, 0.0

    def _schedule(self) -> None:
        if self.length > 0.0:
            self.t += self.dt
            if self.t > self.length:                   # the impulse is over: wait for the next
                self.length, self.wait = 0.0, float(self.rng.uniform(*self.p.every))
            return
        self.wait -= self.dt
        if self.wait <= 0.0:
            self.t, self.length = 0.0, float(self.rng.uniform(*self.p.length))
            self.peak = float(self.rng.uniform(*self.p.peak)) * float(self.rng.choice((-1.0, 1.0)))

    def act(self, record) -> tuple[tuple[float, float], tuple[float, float]]:
        steer, motor, _ = self.expert.act(record)
        self._schedule()
        kick = self.peak * triangle(self.t, self.length) if self.length > 0.0 else 0.0
        return (min(1.0, max(0.0, steer + kick)), motor), (steer, motor)
