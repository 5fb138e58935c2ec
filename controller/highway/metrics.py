"""The highway's closed-loop metrics: what a run achieved and where its time went (the one place they are computed;
the plugin's `metrics(world)` and the benchmark's routes use this class).

Fed once per 10 Hz step, either with the world's observation (`observe`: its truth and flags, the gaps from the
track's own `gap`) or with plain numbers (`update`): speed, the host car's lane and in-lane flag, collision /
off-road flags, and the signed along-track gaps to the other cars in a stable order.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

PASS_WINDOW = 50.0  # [m] a car changes from ahead to behind within this window: an overtake, not the seam
STAGES = ("render", "transfer", "perception", "control", "physics", "traffic", "truth")


@dataclass
class HighwayMetrics:
    track_length: float   # [m]
    dt: float             # [s] one step
    gap: Callable[[float, np.ndarray], np.ndarray] | None = field(default=None, repr=False)   # the track's (observe)
    steps: int = 0
    distance: float = 0.0          # [m]
    collisions: int = 0            # events: steps where a collision begins
    off_road_events: int = 0       # events: steps where the host car's centre leaves the road
    lane_changes: int = 0
    overtakes: int = 0             # cars the host car passed
    overtaken: int = 0             # cars that passed the host car
    in_lane_steps: int = 0
    wall_time: float = 0.0         # [s]
    stage_time: dict = field(default_factory=lambda: {s: 0.0 for s in STAGES})  # [s] summed per stage
    _lane: int | None = None
    _colliding: bool = False
    _off_road: bool = False
    _gaps: np.ndarray | None = None

    @classmethod
    def of(cls, world) -> HighwayMetrics:
        """The metrics of a highway world (sim/highway/world.py): its track's length and gaps, its step."""
        return cls(world.track.length, world.dt, world.track.gap)

    def observe(self, obs) -> None:
        """One step of the world's observation: the host car's truth, the collision and off-road flags."""
        t = obs.truth
        if len(t.cars) and self.gap is None:
            raise ValueError("observing a world needs its track's gap: HighwayMetrics.of(world)")
        gaps = self.gap(t.ego[3], t.cars[:, 3]) if len(t.cars) and self.gap is not None else np.zeros(0)
        self.update(t.speed, t.lanes_left, t.in_lane, obs.collision, obs.off_road, gaps)

    def update(self, speed: float, lane: int, in_lane: bool, collision: bool, off_road: bool, gaps) -> None:
        self.steps += 1
        self.distance += float(speed) * self.dt
        self.collisions += int(collision and not self._colliding)
        self.off_road_events += int(off_road and not self._off_road)
        self._colliding, self._off_road = bool(collision), bool(off_road)
        if self._lane is not None and lane != self._lane:
            self.lane_changes += 1
        self._lane = int(lane)
        self.in_lane_steps += int(in_lane)
        gaps = np.asarray(gaps, dtype=np.float64)
        if self._gaps is not None and len(gaps) == len(self._gaps):
            near = (np.abs(gaps) < PASS_WINDOW) & (np.abs(self._gaps) < PASS_WINDOW)
            self.overtakes += int(np.sum(near & (self._gaps > 0) & (gaps <= 0)))
            self.overtaken += int(np.sum(near & (self._gaps <= 0) & (gaps > 0)))
        self._gaps = gaps

    def add_time(self, stage: str, seconds: float) -> None:
        self.stage_time[stage] = self.stage_time.get(stage, 0.0) + seconds

    def report(self) -> dict:
        sim_time = self.steps * self.dt
        per_step = {k: (v / self.steps * 1e3 if self.steps else 0.0) for k, v in self.stage_time.items()}
        return {
            "simulated_time_s": round(sim_time, 3),
            "distance_m": round(self.distance, 1),
            "laps": round(self.distance / self.track_length, 3),
            "mean_speed_mps": round(self.distance / sim_time, 3) if sim_time else 0.0,
            "collisions": self.collisions,
            "off_road_events": self.off_road_events,
            "lane_changes": self.lane_changes,
            "overtakes": self.overtakes,
            "overtaken": self.overtaken,
            "in_lane_share": round(self.in_lane_steps / self.steps, 4) if self.steps else 0.0,
            "loop_rate_hz": round(self.steps / self.wall_time, 1) if self.wall_time else 0.0,
            "realtime_factor": round(sim_time / self.wall_time, 2) if self.wall_time else 0.0,
            "stage_ms_per_step": {k: round(v, 3) for k, v in per_step.items()},
        }

    def table(self) -> str:
        """The report as a Markdown table."""
        r = self.report()
        stages = r.pop("stage_ms_per_step")
        rows = ["| metric | value |", "|---|---|"] + [f"| {k} | {v} |" for k, v in r.items()]
        rows += [f"| ms/step {k} | {v} |" for k, v in stages.items()]
        return "\n".join(rows)
