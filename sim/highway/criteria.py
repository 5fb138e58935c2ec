"""What a scripted scenario asks of the host car (its "pass", sim/highway/scripted.py), measured step by step from
the world's state, and a digest of everything the world showed, so that two runs can be compared bit for bit.

- no collision: the host's box never overlaps another car's (the world's collision test);
- kept lane: the lane of the host's centre never differs from its start lane;
- minimum time gap: the bumper-to-bumper gap to the nearest car ahead whose centre is in the host's lane, over the
  host's speed, never below the value (counted while the host drives faster than MIN_SPEED; a car overlapping it
  counts 0);
- a host lost off the road fails whatever the criteria.
"""
from __future__ import annotations

import hashlib

import numpy as np

from sim.highway.scripted import Criteria
from sim.highway.traffic import CarStates
from sim.track import Track

MIN_SPEED = 1.0   # [m/s] below this the host stands, and a time gap says nothing


class Judge:
    def __init__(self, criteria: Criteria, track: Track, lane: int, host_length: float):
        self.criteria, self.track, self.lane, self.host_length = criteria, track, lane, host_length
        self.steps = 0
        self.collision_t: float | None = None
        self.left_lane_t: float | None = None
        self.lost_t: float | None = None
        self.min_time_gap: float | None = None
        self.min_time_gap_t: float | None = None
        self._digest = hashlib.sha256()

    def observe(self, obs, cars: CarStates) -> None:
        """One step's observation and the cars it was made of."""
        self.steps += 1
        t = round(float(obs.t), 3)
        for part in (obs.record, cars.poses(), cars.speed):
            self._digest.update(np.ascontiguousarray(part, dtype=np.float64).tobytes())
        if obs.collision and self.collision_t is None:
            self.collision_t = t
        if obs.truth.lanes_left != self.lane and self.left_lane_t is None:
            self.left_lane_t = t
        if obs.lost and self.lost_t is None:
            self.lost_t = t
        gap = self._time_gap(obs.truth, cars)
        if gap is not None and (self.min_time_gap is None or gap < self.min_time_gap):
            self.min_time_gap, self.min_time_gap_t = gap, t

    def _time_gap(self, truth, cars: CarStates) -> float | None:
        speed = float(truth.speed)
        if speed <= MIN_SPEED or not len(cars):
            return None
        ego_s = float(truth.ego[3])
        ahead = np.asarray(self.track.gap(ego_s, cars.s), dtype=np.float64)
        mine = (np.asarray(self.track.lane_of(cars.d)) == int(truth.lanes_left)) & (ahead > 0)
        if not mine.any():
            return None
        bumper = ahead[mine] - (self.host_length + cars.length[mine]) / 2
        return max(0.0, float(bumper.min())) / speed

    def verdict(self) -> dict:
        c = self.criteria
        failed = []
        if c.no_collision and self.collision_t is not None:
            failed.append(f"collision at {self.collision_t:.1f} s")
        if c.kept_lane and self.left_lane_t is not None:
            failed.append(f"left its lane at {self.left_lane_t:.1f} s")
        if c.min_time_gap is not None and self.min_time_gap is not None and self.min_time_gap < c.min_time_gap:
            failed.append(f"time gap {self.min_time_gap:.2f} s at {self.min_time_gap_t:.1f} s, below "
                          f"{c.min_time_gap:g} s")
        if self.lost_t is not None:
            failed.append(f"lost off the road at {self.lost_t:.1f} s")
        return {"passed": not failed, "failed": failed, "collision_t": self.collision_t,
                "left_lane_t": self.left_lane_t,
                "min_time_gap_s": None if self.min_time_gap is None else round(self.min_time_gap, 3),
                "min_time_gap_t": self.min_time_gap_t, "steps": self.steps, "trace_sha256": self._digest.hexdigest()}
