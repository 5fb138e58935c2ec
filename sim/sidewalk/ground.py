"""The ground of both stereo images at once: the highway's ground painter (sim/ground_painter.py: exact projected
polygons, clipped at the near plane, filled by OpenCV in painting order), with the work the two cameras share
done once. The cameras of a parallel rig share their orientation and differ by the baseline along their x axis,
so a point's camera coordinates in the left and right cameras are those in the rig's centre camera shifted by
+-baseline / 2 in x: one transform, one depth test and one near-plane clip serve both images.

Polygons wholly outside one plane of both eyes' view frustum are skipped (exact), and so are the ground's details
(patches, stains, joints, shadows: the `detail` materials) in chunks beyond the detail reach, where they are
thinner than a pixel.
"""
from __future__ import annotations

import cv2
import numpy as np

from sim.ground_painter import SUBPIXEL_BITS, GroundPainter


class StereoGroundPainter(GroundPainter):
    """`camera` is the rig's centre camera (eye_left = 0); `baseline` [m] between the two eyes; `materials` in
    painting order, of which `detail` are skipped in chunks not marked near."""

    def __init__(self, chunks, look, camera, materials, baseline: float, detail=()):
        super().__init__(chunks, look, camera, materials=materials)
        self.half = baseline / 2
        self._detail = np.array([m in detail for m in materials])
        self._tx = (camera.width / 2 + 1) / self._fx
        self._ty = (camera.height / 2 + 1) / self._fy

    def paint_pair(self, left: np.ndarray, right: np.ndarray, visible: np.ndarray, near_chunks: np.ndarray,
                   x: float, y: float, yaw: float) -> int:
        """Paint the ground of the visible chunks (details only in the near ones) into both frames; returns the
        polygons painted."""
        idx = [int(i) for i in np.flatnonzero(visible) if len(self._tables[i])]
        if not idx:
            return 0
        offsets = np.cumsum([0] + [len(self._verts[i]) for i in idx])
        verts = np.concatenate([self._verts[i] for i in idx])
        table = np.concatenate([self._tables[i] + [0, o, o] for i, o in zip(idx, offsets[:-1])])
        is_near = np.concatenate([np.full(len(self._tables[i]), bool(near_chunks[i])) for i in idx])
        eye, basis = self.camera.basis(x, y, yaw)
        cam = (verts - eye) @ basis.T
        near, h, tx, ty = self.camera.near, self.half, self._tx, self._ty
        starts = table[:, 1]
        x_, y_, z_ = cam[:, 0], cam[:, 1], cam[:, 2]
        lo = np.minimum.reduceat(z_, starts)
        hi = np.maximum.reduceat(z_, starts)
        inside = (hi > near) & (np.minimum.reduceat(x_ - h - z_ * tx, starts) < 0) & \
            (np.minimum.reduceat(-x_ - h - z_ * tx, starts) < 0) & \
            (np.minimum.reduceat(y_ - z_ * ty, starts) < 0) & (np.minimum.reduceat(-y_ - z_ * ty, starts) < 0)
        inside &= is_near | ~self._detail[table[:, 0]]
        order = [k for k in np.argsort(table[:, 0], kind="stable").tolist() if inside[k]]
        shift = np.array([h, 0.0, 0.0])
        with np.errstate(divide="ignore", invalid="ignore"):
            pix_l, pix_r = self._to_pixels(cam + shift), self._to_pixels(cam - shift)
        fill, line = cv2.fillPoly, cv2.LINE_8
        n = 0
        for k in order:
            rank, a, b = table[k]
            if lo[k] >= near:
                pl, pr = pix_l[a:b], pix_r[a:b]
            else:
                clipped = self._clip_near(cam[a:b])
                if len(clipped) < 3:
                    continue
                pl, pr = self._to_pixels(clipped + shift), self._to_pixels(clipped - shift)
            colour = self._colours[rank]
            fill(left, [pl], colour, line, SUBPIXEL_BITS)
            fill(right, [pr], colour, line, SUBPIXEL_BITS)
            n += 1
        return n
