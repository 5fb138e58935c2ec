"""The sidewalk's closed-loop metrics (controller/sidewalk/metrics.py) fed from its observations."""
from __future__ import annotations

from controller.sidewalk import SidewalkMetrics


class Metrics:
    """controller/sidewalk/metrics.py fed from the world's observations."""

    def __init__(self, world):
        self.m = SidewalkMetrics(world.dt)

    def observe(self, obs) -> None:
        self.m.update(obs.record)

    def __getattr__(self, name):
        return getattr(self.m, name)

    def __setattr__(self, name, value):
        if name == "m":
            object.__setattr__(self, name, value)
        else:
            setattr(self.m, name, value)
