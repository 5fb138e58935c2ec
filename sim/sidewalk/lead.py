"""The lead car of follow mode: a second 1/10-scale car driving ahead along the path at a varying speed.

It keeps to a line that swings round every obstacle (on the side with more room) and otherwise holds the
centreline; its speed changes every few seconds to a new target drawn from the seed (now and then it stops),
limited by the bends ahead and by gentle acceleration. Everything is a function of the seed: the same run, the
same lead car.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.sidewalk.car import CAR
from sim.sidewalk.layout import Layout

SPEED_RANGE = (0.8, 3.2)       # [m/s] targets drawn for the lead car
STOP_ODDS = 0.12               # share of targets that are a stop
HOLD = (2.0, 6.0)              # [s] a target holds this long
ACCEL = 1.5                    # [m/s^2] gentle speed changes
LATERAL_ACCEL = 1.2            # [m/s^2] in bends
RAMP_IN, RAMP_OUT = 2.5, 1.5   # [m] of path over which it swings out before an obstacle and back after it
CLEAR = 0.35                   # [m] more than half the car's length: the swing holds this long before and after
START_GAP = 1.6                # [m] from the follower's front to the lead's rear when it appears


def passing_offset(path_half_width: float, obstacle_d: float, obstacle_across: float) -> float:
    """Lateral offset [m] at which to pass an obstacle: the middle of the larger free width beside it."""
    left_edge, right_edge = obstacle_d + obstacle_across / 2, obstacle_d - obstacle_across / 2
    room_left, room_right = path_half_width - left_edge, right_edge + path_half_width
    if room_left >= room_right:
        return (left_edge + path_half_width) / 2
    return (right_edge - path_half_width) / 2


def _smooth(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(math.pi * u)


class LeadLine:
    """d(s) [m]: the lead car's lateral offset along the path."""

    def __init__(self, layout: Layout):
        self.track = layout.path.track
        hw = layout.path.half_width
        self.centre = np.array([o.s for o in layout.obstacles])
        self.half = np.array([o.along / 2 + CLEAR + CAR.length / 2 for o in layout.obstacles])
        self.offset = np.array([passing_offset(hw, o.d, o.across) for o in layout.obstacles])

    def __call__(self, s: float) -> float:
        if not len(self.centre):
            return 0.0
        g = self.track.gap(self.centre, s)   # s - centre, wrapped
        half = self.half
        w = np.where(g < 0, _smooth((g + half + RAMP_IN) / RAMP_IN), _smooth((half + RAMP_OUT - g) / RAMP_OUT))
        w = np.where(np.abs(g) <= half, 1.0, w)
        return float(np.dot(w, self.offset))


@dataclass
class LeadState:
    s: float
    d: float
    speed: float
    yaw: float = 0.0       # [rad] world heading
    x: float = 0.0
    y: float = 0.0


class LeadCar:
    def __init__(self, layout: Layout, seed: int, s: float, speed: float):
        self.layout = layout
        self.track = layout.path.track
        self.line = LeadLine(layout)
        self.rng = np.random.default_rng([int(seed), 0x1EAD])
        self.target = max(0.8, speed)
        self.hold = float(self.rng.uniform(*HOLD))
        self.state = self._pose(self.track.wrap_s(s), max(0.0, speed))

    def _pose(self, s: float, speed: float) -> LeadState:
        d = float(self.line(s))
        ds = 0.05
        slope = (float(self.line(s + ds)) - float(self.line(s - ds))) / (2 * ds)
        x, y, h = self.track.pose(s, d)
        kappa = self.track.curvature(s)
        return LeadState(s, d, speed, h + math.atan2(slope, 1.0 - kappa * d), x, y)

    def _bend_limit(self, s: float) -> float:
        """The speed the bends of the next 3 m allow."""
        k = max(abs(self.track.curvature(s + a)) for a in (0.0, 1.0, 2.0, 3.0))
        return math.sqrt(LATERAL_ACCEL / k) if k > 0 else math.inf

    def step(self, dt: float) -> LeadState:
        self.hold -= dt
        if self.hold <= 0:
            self.hold = float(self.rng.uniform(*HOLD))
            self.target = 0.0 if self.rng.uniform() < STOP_ODDS else float(self.rng.uniform(*SPEED_RANGE))
        st = self.state
        want = min(self.target, self._bend_limit(st.s))
        v = st.speed + max(-ACCEL * dt, min(ACCEL * dt, want - st.speed))
        v = max(0.0, v)
        d = st.d
        kappa = self.track.curvature(st.s)
        s = self.track.wrap_s(st.s + v * dt / max(0.2, 1.0 - kappa * d))   # along the centreline
        self.state = self._pose(s, v)
        return self.state
