"""The exact truth record of the sidewalk world (SIDEWALK's fields, core/worlds/sidewalk.py), from geometry.

The car is integrated in path coordinates (s, d, heading), so its pose is exact; the body's corners are
projected onto the path (Track.frenet) to measure its clearance to the borders; obstacles and the lead car are
placed in path coordinates by construction; collisions are oriented-rectangle overlaps (sim/collision.py).
"""
from __future__ import annotations

import math

import numpy as np

from core.worlds.sidewalk import SIDEWALK
from sim.collision import overlaps
from sim.sidewalk.car import CAR, CarParams, CarState
from sim.sidewalk.layout import BORDER_CAP, Layout
from sim.sidewalk.lead import LeadState

GAP_CAP = 30.0          # [m] obstacle_gap and lead_gap when there is nothing within reach
NEAR = 3.0              # [m] obstacle_near below this gap
PREVIEW = 1.5           # [m] curvature_ahead averages the path's turn over this much path
LOST_MARGIN = 1.0       # [m] beyond the path's edge the car is lost: the episode cannot go on

_NAMES = SIDEWALK.truth_names
_I = {n: i for i, n in enumerate(_NAMES)}


def corners(x: float, y: float, yaw: float, p: CarParams = CAR) -> np.ndarray:
    """(4, 2) world corners of the car's body."""
    c, s = math.cos(yaw), math.sin(yaw)
    local = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]], dtype=np.float64) * (p.length / 2, p.width / 2)
    return np.column_stack((x + c * local[:, 0] - s * local[:, 1], y + s * local[:, 0] + c * local[:, 1]))


def border_clearance(layout: Layout, car_s: float, corner_s: np.ndarray, corner_d: np.ndarray) -> tuple[float, float]:
    """(left, right) clearance [m] from the body's outermost corner to the border's face on each side, where a
    border stretch stands beside the car's centre or one of its corners; BORDER_CAP where none does."""
    out = []
    for border, sign in zip(layout.borders, (1.0, -1.0)):
        faces = [border.face[i] for i in {border.at(s) for s in (car_s, *corner_s.tolist())} if i is not None]
        if not faces:
            out.append(BORDER_CAP)
            continue
        reach = float(np.max(sign * corner_d))              # how far the body reaches towards that side
        out.append(min(BORDER_CAP, min(sign * f for f in faces) - reach))
    return out[0], out[1]


def next_obstacle(layout: Layout, car_s: float, p: CarParams = CAR) -> tuple[float, float, float]:
    """(gap, d, across) of the next obstacle not yet passed: gap [m] from the car's front to its near edge along
    the path (negative while alongside), or (GAP_CAP, 0, 0) when none is within GAP_CAP."""
    if not len(layout.obstacle_s):
        return GAP_CAP, 0.0, 0.0
    rel = layout.path.track.gap(car_s, layout.obstacle_s)               # centre ahead of the car's centre [m]
    not_passed = rel + layout.obstacle_along / 2 > -p.length / 2         # its far edge beyond the car's rear
    if not not_passed.any():
        return GAP_CAP, 0.0, 0.0
    idx = np.flatnonzero(not_passed)
    k = int(idx[np.argmin(rel[idx])])
    gap = float(rel[k] - layout.obstacle_along[k] / 2 - p.length / 2)
    if gap >= GAP_CAP:
        return GAP_CAP, 0.0, 0.0
    return gap, float(layout.obstacle_d[k]), float(layout.obstacle_across[k])


def truth_record(layout: Layout, car: CarState, lead: LeadState | None, command: tuple[float, float],
                 behaviour: int, operation: int, correcting: bool, p: CarParams = CAR) -> tuple[np.ndarray, bool]:
    """(the truth record, float64 in SIDEWALK's order; whether the car is lost off the path)."""
    track = layout.path.track
    hw = layout.path.half_width
    x, y, tangent = track.pose(car.s, car.d)
    yaw = tangent + car.heading
    box = corners(x, y, yaw, p)
    cs, cd = track.frenet(box[:, 0], box[:, 1], s_hint=np.full(4, car.s))
    left, right = border_clearance(layout, car.s, cs, cd)
    gap, od, ow = next_obstacle(layout, car.s, p)
    rec = np.empty(len(_NAMES))
    rec[_I["steer"]], rec[_I["motor"]] = command
    rec[_I["behaviour"]], rec[_I["operation"]], rec[_I["correcting"]] = behaviour, operation, correcting
    rec[_I["speed"]] = car.speed
    rec[_I["x"]], rec[_I["y"]] = x, y
    rec[_I["yaw"]] = math.remainder(yaw, 2 * math.pi)
    rec[_I["s"]], rec[_I["d"]], rec[_I["heading"]] = car.s, car.d, car.heading
    rec[_I["path_width"]] = layout.path.width
    rec[_I["curvature"]] = track.curvature(car.s)
    h0, h1 = track.heading(car.s), track.heading(car.s + PREVIEW)
    turn = math.remainder(h1 - h0, 2 * math.pi)
    rec[_I["curvature_ahead"]] = turn / PREVIEW
    rec[_I["border_left"]], rec[_I["border_right"]] = left, right
    rec[_I["obstacle_gap"]], rec[_I["obstacle_d"]], rec[_I["obstacle_width"]] = gap, od, ow
    touching = bool(overlaps((x, y, yaw, p.length, p.width), layout.obstacle_boxes).any()) or \
        bool(overlaps((x, y, yaw, p.length, p.width), layout.tree_boxes).any()) or left <= 0.0 or right <= 0.0
    if lead is not None:
        lead_gap = float(track.gap(car.s, lead.s)) - p.length
        rec[_I["lead_gap"]] = min(GAP_CAP, lead_gap)
        rec[_I["lead_d"]], rec[_I["lead_speed"]] = lead.d, lead.speed
        touching = touching or bool(overlaps((x, y, yaw, p.length, p.width),
                                             np.array([[lead.x, lead.y, lead.yaw, p.length, p.width]])).any())
    else:
        rec[_I["lead_gap"]], rec[_I["lead_d"]], rec[_I["lead_speed"]] = GAP_CAP, 0.0, 0.0
    rec[_I["obstacle_near"]] = gap < NEAR
    rec[_I["collision"]] = touching
    rec[_I["off_path"]] = abs(car.d) > hw
    return rec, abs(car.d) > hw + LOST_MARGIN
