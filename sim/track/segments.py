"""Centreline segments: one interface, one small class per kind.

Every segment starts at a pose (x0 [m], y0 [m], heading0 [rad], counter-clockwise from +x) and is
parametrised by its local arc length t in [0, length] [m]. Lateral offsets d [m] are positive to the left
of the driving direction. All methods accept numpy arrays as well as floats.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np


def wrap_angle(a):
    """Wrap an angle [rad] into (-pi, pi]; angles already in range come back unchanged, bit for bit."""
    if np.ndim(a) == 0:
        r = math.remainder(float(a), 2 * math.pi)
        return math.pi if r == -math.pi else r
    a = np.asarray(a, dtype=np.float64)
    wrapped = np.pi - np.mod(np.pi - a, 2 * np.pi)
    return np.where((a > -np.pi) & (a <= np.pi), a, wrapped)


class Segment(ABC):
    kind: str
    length: float      # [m]
    curvature: float   # [1/m], positive when turning left

    def __init__(self, x0: float, y0: float, heading0: float):
        self.x0, self.y0, self.heading0 = float(x0), float(y0), float(heading0)

    @abstractmethod
    def position(self, t, d=0.0):
        """World (x, y) [m] of the point at local arc length t and lateral offset d."""

    @abstractmethod
    def heading(self, t):
        """Tangent yaw [rad] at local arc length t (not wrapped)."""

    @abstractmethod
    def local_coordinates(self, x, y):
        """(t, d) of a world point; t may fall outside [0, length] when the point is beside another segment."""

    def end_pose(self) -> tuple[float, float, float]:
        x, y = self.position(self.length)
        return float(x), float(y), float(self.heading(self.length))


class Straight(Segment):
    kind = "straight"
    curvature = 0.0

    def __init__(self, x0, y0, heading0, length: float):
        super().__init__(x0, y0, heading0)
        self.length = float(length)
        self._c, self._s = math.cos(self.heading0), math.sin(self.heading0)

    def position(self, t, d=0.0):
        return (self.x0 + t * self._c - d * self._s,
                self.y0 + t * self._s + d * self._c)

    def heading(self, t):
        return np.full(np.shape(t), self.heading0) if np.ndim(t) else self.heading0

    def local_coordinates(self, x, y):
        vx, vy = x - self.x0, y - self.y0
        return vx * self._c + vy * self._s, -vx * self._s + vy * self._c


class Arc(Segment):
    """A circular arc of `radius` [m] sweeping `angle` [rad]; positive angle turns left."""

    kind = "arc"

    def __init__(self, x0, y0, heading0, radius: float, angle: float):
        super().__init__(x0, y0, heading0)
        self.radius, self.angle = float(radius), float(angle)
        self.length = self.radius * abs(self.angle)
        self.curvature = math.copysign(1.0 / self.radius, self.angle)
        # centre of the circle: on the left for a left turn, on the right for a right turn
        self.cx = self.x0 - math.sin(self.heading0) / self.curvature
        self.cy = self.y0 + math.cos(self.heading0) / self.curvature

    def position(self, t, d=0.0):
        h = self.heading0 + self.curvature * t
        r = 1.0 / self.curvature - d
        return self.cx + r * np.sin(h), self.cy - r * np.cos(h)

    def heading(self, t):
        return self.heading0 + self.curvature * t

    def local_coordinates(self, x, y):
        ux, uy = x - self.cx, y - self.cy
        dist = np.hypot(ux, uy)
        if self.curvature > 0:
            h = np.arctan2(ux, -uy)
            d = self.radius - dist
        else:
            h = np.arctan2(-ux, uy)
            d = dist - self.radius
        # turn measured from the start, wrapped around the middle of the arc so that t is continuous on it
        half = 0.5 * self.angle
        turn = wrap_angle(h - self.heading0 - half) + half
        return turn / self.curvature, d
