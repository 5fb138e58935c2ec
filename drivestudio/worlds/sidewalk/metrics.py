"""The sidewalk's closed-loop metrics (controller/sidewalk/metrics.py) fed from its observations, with the take-overs
of its correction rule by clause."""
from __future__ import annotations

from controller.sidewalk import SidewalkMetrics
from drivestudio.worlds.sidewalk.drivers import SUPERVISORS


class Metrics:
    """controller/sidewalk/metrics.py fed from the world's observations."""

    def __init__(self, world):
        self.m = SidewalkMetrics(world.dt)
        self.world = world

    def observe(self, obs) -> None:
        self.m.update(obs.record)

    def report(self) -> dict:
        supervisor = SUPERVISORS.get(self.world)
        if supervisor is not None and supervisor.operation == "correctional":
            self.m.rule = supervisor.rule.rule
            self.m.clauses = supervisor.rule.tally.report(self.m.dt)
        return self.m.report()

    def table(self) -> str:
        self.report()
        return self.m.table()

    def __getattr__(self, name):
        return getattr(self.m, name)

    def __setattr__(self, name, value):
        if name in ("m", "world"):
            object.__setattr__(self, name, value)
        else:
            setattr(self.m, name, value)
