"""The highway's closed-loop metrics (controller/highway/metrics.py) fed from its observations."""
from __future__ import annotations

import numpy as np

from controller.highway.metrics import ClosedLoopMetrics


class HighwayMetrics:
    """controller/highway/metrics.py's ClosedLoopMetrics, fed from the highway's observations."""

    def __init__(self, world):
        self.m = ClosedLoopMetrics(world.track.length, world.dt)
        self.world = world

    def observe(self, obs) -> None:
        t = obs.truth
        gaps = self.world.track.gap(t.ego[3], t.cars[:, 3]) if len(t.cars) else np.zeros(0)
        self.m.update(t.speed, t.lanes_left, t.in_lane, obs.collision, obs.off_road, gaps)

    def __getattr__(self, name):
        return getattr(self.m, name)

    def __setattr__(self, name, value):
        if name in ("m", "world"):
            object.__setattr__(self, name, value)
        else:
            setattr(self.m, name, value)
