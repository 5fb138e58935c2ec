"""A top-down picture of the world around the car, drawn from its geometry (not from any camera): the path, the
borders, trees, obstacles, the lead car and the car, the car's heading pointing up. For videos and the docs."""
from __future__ import annotations

import math

import cv2
import numpy as np

from sim.sidewalk.car import CAR
from sim.sidewalk.layout import Layout
from sim.sidewalk.shapes import rectangle

SHIFT = 3    # cv2 fixed-point bits
COLOURS = {"grass": (96, 140, 70), "path": (200, 196, 186), "edge": (120, 118, 112), "hedge": (35, 90, 35),
           "bushes": (60, 120, 50), "trunk": (90, 60, 40), "crown": (50, 105, 50), "car": (220, 30, 30),
           "lead": (30, 70, 220), "cone": (255, 120, 0), "post": (90, 90, 90), "bench": (140, 90, 50),
           "bike": (40, 160, 200), "pedestrian": (200, 60, 200)}


class TopDown:
    def __init__(self, layout: Layout, size: int = 188, span: float = 14.0):
        """size [px] of the square picture, span [m] of ground it shows across."""
        self.layout, self.size, self.scale = layout, size, size / span
        track = layout.path.track
        s = np.arange(0.0, track.length, 0.2)
        x, y, _ = track.pose(s)
        self._centre = np.column_stack((x, y))
        self._borders = []
        for b in layout.borders:
            for k in range(len(b.starts)):
                ss = np.arange(b.starts[k], b.ends[k], 0.2)
                bx, by, _ = track.pose(ss, b.face[k] + b.side * b.depths[k] / 2)
                self._borders.append((np.column_stack((bx, by)), b.depths[k], b.kinds[k]))
        self._trees = np.array([(t.x, t.y, t.trunk, t.crown) for t in layout.trees]).reshape(-1, 4)
        self._obstacles = [(rectangle(o.x, o.y, o.world_yaw, o.length, o.width), o.kind) for o in layout.obstacles]

    def _px(self, pts: np.ndarray, x: float, y: float, yaw: float) -> np.ndarray:
        """World points (n, 2) to fixed-point pixels: the car at 70 % of the height, heading up."""
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = pts[:, 0] - x, pts[:, 1] - y
        fwd, left = c * dx + s * dy, -s * dx + c * dy
        u = self.size / 2 - left * self.scale
        v = self.size * 0.7 - fwd * self.scale
        return np.round(np.column_stack((u, v)) * (1 << SHIFT)).astype(np.int32)

    def draw(self, x: float, y: float, yaw: float, lead=None) -> np.ndarray:
        """(size, size, 3) uint8 RGB around a car at (x, y, yaw); `lead` with x, y, yaw or None."""
        img = np.empty((self.size, self.size, 3), np.uint8)
        img[:] = COLOURS["grass"]
        reach = self.size / self.scale
        near = np.hypot(self._centre[:, 0] - x, self._centre[:, 1] - y) < reach
        w = self.layout.path.width
        for run in _runs(near):
            pts = self._px(self._centre[run], x, y, yaw)
            cv2.polylines(img, [pts], False, COLOURS["edge"], max(1, int(round((w + 0.12) * self.scale))),
                          cv2.LINE_AA, SHIFT)
            cv2.polylines(img, [pts], False, COLOURS["path"], max(1, int(round(w * self.scale))), cv2.LINE_AA, SHIFT)
        for pts, depth, kind in self._borders:
            close = np.hypot(pts[:, 0] - x, pts[:, 1] - y) < reach
            for run in _runs(close):
                cv2.polylines(img, [self._px(pts[run], x, y, yaw)], False, COLOURS[kind],
                              max(1, int(round(depth * self.scale))), cv2.LINE_AA, SHIFT)
        if len(self._trees):
            close = np.hypot(self._trees[:, 0] - x, self._trees[:, 1] - y) < reach + 3
            for tx, ty, trunk, crown in self._trees[close]:
                p = self._px(np.array([[tx, ty]]), x, y, yaw)[0]
                cv2.circle(img, tuple(p), int(crown * self.scale * (1 << SHIFT)), COLOURS["crown"], 1, cv2.LINE_AA,
                           SHIFT)
                cv2.circle(img, tuple(p), max(1 << SHIFT, int(trunk * self.scale * (1 << SHIFT))), COLOURS["trunk"],
                           -1, cv2.LINE_AA, SHIFT)
        for corners, kind in self._obstacles:
            if np.hypot(corners[0, 0] - x, corners[0, 1] - y) < reach:
                cv2.fillConvexPoly(img, self._px(corners, x, y, yaw), COLOURS[kind], cv2.LINE_AA, SHIFT)
        if lead is not None:
            cv2.fillConvexPoly(img, self._px(rectangle(lead.x, lead.y, lead.yaw, CAR.length, CAR.width), x, y, yaw),
                               COLOURS["lead"], cv2.LINE_AA, SHIFT)
        cv2.fillConvexPoly(img, self._px(rectangle(x, y, yaw, CAR.length, CAR.width), x, y, yaw), COLOURS["car"],
                           cv2.LINE_AA, SHIFT)
        return img


def _runs(mask: np.ndarray) -> list[np.ndarray]:
    """Index arrays of the runs of True in mask (consecutive samples)."""
    idx = np.flatnonzero(mask)
    if not len(idx):
        return []
    breaks = np.flatnonzero(np.diff(idx) > 1) + 1
    return [r for r in np.split(idx, breaks) if len(r) > 1]
