"""The ground of both stereo images at once: the highway's ground painter (sim/ground_painter.py: exact projected
polygons, clipped at the near plane, filled by OpenCV in painting order), with the work the two cameras share
done once. The cameras of a parallel rig share their orientation and differ by the baseline along their x axis,
so a point's camera coordinates in the left and right cameras are those in the rig's centre camera shifted by
+-baseline / 2 in x: one transform, one depth test and one near-plane clip serve both images.
"""
from __future__ import annotations

import cv2
import numpy as np

from sim.ground_painter import SUBPIXEL_BITS, GroundPainter


class StereoGroundPainter(GroundPainter):
    """`camera` is the rig's centre camera (eye_left = 0); `baseline` [m] between the two eyes."""

    def __init__(self, chunks, look, camera, materials, baseline: float):
        super().__init__(chunks, look, camera, materials=materials)
        self.half = baseline / 2

    def paint_pair(self, left: np.ndarray, right: np.ndarray, visible: np.ndarray, x: float, y: float,
                   yaw: float) -> int:
        """Paint the ground of the visible chunks into both frames; returns the polygons painted."""
        idx = [int(i) for i in np.flatnonzero(visible) if len(self._tables[i])]
        if not idx:
            return 0
        offsets = np.cumsum([0] + [len(self._verts[i]) for i in idx])
        verts = np.concatenate([self._verts[i] for i in idx])
        table = np.concatenate([self._tables[i] + [0, o, o] for i, o in zip(idx, offsets[:-1])])
        eye, basis = self.camera.basis(x, y, yaw)
        cam = (verts - eye) @ basis.T
        near = self.camera.near
        lo = np.minimum.reduceat(cam[:, 2], table[:, 1])
        hi = np.maximum.reduceat(cam[:, 2], table[:, 1])
        shift = np.array([self.half, 0.0, 0.0])   # the left eye sits half a baseline left: points move right
        with np.errstate(divide="ignore", invalid="ignore"):
            pix_l = self._to_pixels(cam + shift)
            pix_r = self._to_pixels(cam - shift)
        n = 0
        fill, line = cv2.fillPoly, cv2.LINE_8
        for k in np.argsort(table[:, 0], kind="stable").tolist():
            if hi[k] < near:
                continue
            rank, a, b = table[k]
            colour = self._colours[rank]
            if lo[k] >= near:
                pl, pr = pix_l[a:b], pix_r[a:b]
            else:
                clipped = self._clip_near(cam[a:b])
                if len(clipped) < 3:
                    continue
                pl, pr = self._to_pixels(clipped + shift), self._to_pixels(clipped - shift)
            fill(left, [pl], colour, line, SUBPIXEL_BITS)
            fill(right, [pr], colour, line, SUBPIXEL_BITS)
            n += 1
        return n
