"""Collisions between cars as oriented rectangles in the ground plane (separating-axis test)."""
from __future__ import annotations

import numpy as np

SLACK = 1e-6   # [m] far above the rounding of a projection (about 1e-13 m at 1 km), far below any gap that matters


def _corners(x, y, yaw, length, width) -> np.ndarray:
    """(n, 4, 2) corners of rectangles centred at (x, y) [m], turned by yaw [rad]."""
    c, s = np.cos(yaw), np.sin(yaw)
    hl, hw = np.asarray(length) / 2, np.asarray(width) / 2
    local = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]], dtype=np.float64)
    lx = local[None, :, 0] * np.atleast_1d(hl)[:, None]
    ly = local[None, :, 1] * np.atleast_1d(hw)[:, None]
    c, s = np.atleast_1d(c)[:, None], np.atleast_1d(s)[:, None]
    return np.stack([np.atleast_1d(x)[:, None] + c * lx - s * ly, np.atleast_1d(y)[:, None] + s * lx + c * ly],
                    axis=-1)


def _apart_along_a(a, b: np.ndarray) -> np.ndarray:
    """Which rectangles b (m, 5) lie clear of a along one of a's own axes by more than SLACK: their bounding circles
    already do, so the separating-axis test would find that axis too. A car in the next lane is such a case, and
    this test costs a fraction of the full one."""
    c, s = np.cos(a[2]), np.sin(a[2])
    dx, dy = b[:, 0] - a[0], b[:, 1] - a[1]
    rb = np.hypot(b[:, 3], b[:, 4]) / 2
    return (np.abs(dx * c + dy * s) > a[3] / 2 + rb + SLACK) | (np.abs(dy * c - dx * s) > a[4] / 2 + rb + SLACK)


def overlaps(a, others: np.ndarray) -> np.ndarray:
    """Which of `others` overlap rectangle `a`. a: (x, y, yaw, length, width); others: (n, 5), same columns."""
    others = np.asarray(others, dtype=np.float64).reshape(-1, 5)
    out = np.zeros(len(others), dtype=bool)
    if not len(others):
        return out
    reach = (np.hypot(a[3], a[4]) + np.hypot(others[:, 3], others[:, 4])) / 2
    near = np.hypot(others[:, 0] - a[0], others[:, 1] - a[1]) < reach
    if near.any():
        near[near] = ~_apart_along_a(a, others[near])
    if not near.any():
        return out
    b = others[near]
    ca = _corners(a[0], a[1], a[2], a[3], a[4])          # (1, 4, 2)
    cb = _corners(b[:, 0], b[:, 1], b[:, 2], b[:, 3], b[:, 4])  # (m, 4, 2)
    axes = [np.array([np.cos(a[2]), np.sin(a[2])]), np.array([-np.sin(a[2]), np.cos(a[2])])]
    separated = np.zeros(len(b), dtype=bool)
    for axis in axes:  # a's own axes
        pa = ca[0] @ axis
        pb = cb @ axis
        separated |= (pb.max(axis=1) < pa.min()) | (pb.min(axis=1) > pa.max())
    for k in range(2):  # each of b's axes
        axis = np.stack([np.cos(b[:, 2]), np.sin(b[:, 2])], axis=1) if k == 0 else \
            np.stack([-np.sin(b[:, 2]), np.cos(b[:, 2])], axis=1)
        pa = np.einsum("ij,kj->ki", ca[0], axis)          # (m, 4)
        pb = np.einsum("mij,mj->mi", cb, axis)            # (m, 4)
        separated |= (pb.max(axis=1) < pa.min(axis=1)) | (pb.min(axis=1) > pa.max(axis=1))
    out[np.flatnonzero(near)] = ~separated
    return out
