"""A deliberately poor driver, to exercise correctional operation before any network exists.

It is the mode's expert (controller/sidewalk/experts.py) with a human's worst habits: a steering bias that wanders
slowly (an Ornstein-Uhlenbeck process), a little too much speed, and lapses of attention every several seconds
during which it holds its steering as it was, whatever the path and the obstacles do. On a winding path a lapse
soon takes it towards the edge, a border or an obstacle, and the correction rule takes over. It reads the truth
record only, as any driver over the bridge does; its randomness is a function of its seed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controller.sidewalk.experts import SidewalkExpert, motor_command
from core.worlds.sidewalk import STEP, TOP_SPEED


@dataclass(frozen=True)
class PoorParams:
    bias_sigma: float = 0.08        # steering units: the wandering bias's spread
    bias_tau: float = 3.0           # [s] how slowly it wanders
    lapse_every: tuple = (4.0, 10.0)   # [s] between lapses
    lapse_length: tuple = (1.0, 2.5)   # [s]
    speed_factor: float = 1.2


class PoorDriver:
    def __init__(self, seed: int = 0, params: PoorParams = PoorParams(), dt: float = STEP):
        self.p, self.dt = params, dt
        self.rng = np.random.default_rng([int(seed), 0x9002])
        self.expert = SidewalkExpert()
        self.bias = 0.0
        self.until_lapse = float(self.rng.uniform(*params.lapse_every))
        self.lapse = 0.0
        self.held = 0.5

    def act(self, record) -> tuple[float, float]:
        """(steer, motor) for a truth record."""
        p = self.p
        steer, motor, _ = self.expert.act(record)
        self.bias += -self.bias / p.bias_tau * self.dt + p.bias_sigma * math.sqrt(2 * self.dt / p.bias_tau) * \
            float(self.rng.normal())
        if self.lapse > 0:
            self.lapse -= self.dt
            steer = self.held
        else:
            self.until_lapse -= self.dt
            if self.until_lapse <= 0:
                self.lapse = float(self.rng.uniform(*p.lapse_length))
                self.until_lapse = float(self.rng.uniform(*p.lapse_every))
                self.held = steer + self.bias
        speed = (motor - 0.5) * 2 * TOP_SPEED * p.speed_factor
        return min(1.0, max(0.0, steer + self.bias)), motor_command(speed)
