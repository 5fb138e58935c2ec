"""Other cars: their state as the world sees it, and the scripted traffic of scenarios.

AI traffic driven by SUMO lives in sim/highway/sumo_traffic.py and fills the same CarStates.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.highway.car_models import PAINTS, car_models
from sim.track import Track


@dataclass
class CarStates:
    """The other cars at one instant, one entry per car, in a stable order."""

    x: np.ndarray       # [m]
    y: np.ndarray       # [m]
    yaw: np.ndarray     # [rad]
    s: np.ndarray       # [m]
    d: np.ndarray       # [m]
    length: np.ndarray  # [m]
    width: np.ndarray   # [m]
    models: np.ndarray  # index into car_models()
    paints: np.ndarray  # index into PAINTS
    speed: np.ndarray   # [m/s] along the car's heading
    ids: np.ndarray | None = None   # which car each entry is, the same from step to step (SUMO inserts some late)

    @classmethod
    def empty(cls) -> CarStates:
        z = np.zeros(0)
        return cls(z, z, z, z, z, z, z, np.zeros(0, int), np.zeros(0, int), z)

    def __len__(self) -> int:
        return len(self.s)

    def poses(self) -> np.ndarray:
        """(n, 5): x, y, yaw, s, d."""
        return np.stack([self.x, self.y, self.yaw, self.s, self.d], axis=1).reshape(-1, 5)

    def boxes(self) -> np.ndarray:
        """(n, 5): x, y, yaw, length, width."""
        return np.stack([self.x, self.y, self.yaw, self.length, self.width], axis=1).reshape(-1, 5)


def assign_looks(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Seeded car model and paint for each of n cars."""
    rng = np.random.default_rng([int(seed), 0xCA5])
    return rng.integers(0, len(car_models()), n), rng.integers(0, len(PAINTS), n)


class ScriptedTraffic:
    """Cars that keep their lane offset at a constant speed (scenarios, tests)."""

    def __init__(self, track: Track, s, d, speed, seed: int = 0):
        self.track = track
        self._s0 = np.asarray(s, dtype=np.float64)
        self.d = np.asarray(d, dtype=np.float64)
        self.speed = np.asarray(speed, dtype=np.float64)
        self.models, self.paints = assign_looks(len(self._s0), seed)
        dims = np.array([(m.length, m.width) for m in car_models()]).reshape(-1, 2)
        self.length, self.width = dims[self.models, 0], dims[self.models, 1]
        self.reset()

    def reset(self) -> None:
        self.s = self.track.wrap_s(self._s0.copy())

    def step(self, dt: float, ego=None, ego_speed: float = 0.0) -> None:
        self.s = self.track.wrap_s(self.s + self.speed * dt)

    def states(self) -> CarStates:
        if not len(self.s):
            return CarStates.empty()
        x, y, yaw = self.track.pose(self.s, self.d)
        return CarStates(x, y, yaw, self.s.copy(), self.d.copy(), self.length, self.width, self.models,
                         self.paints, self.speed.copy(), np.arange(len(self.s)))

    def close(self) -> None:
        pass
