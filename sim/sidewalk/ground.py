"""The ground of both stereo images at once: the highway's ground painter (sim/ground_painter.py: exact projected
polygons, clipped at the near plane, filled in painting order), with the work the two cameras share done once. The
cameras of a parallel rig share their orientation and differ by the baseline along their x axis, so a point's camera
coordinates in the left and right cameras are those in the rig's centre camera shifted by +-baseline / 2 in x: one
transform, one depth test and one near-plane clip serve both images.

Polygons wholly outside one plane of both eyes' view frustum are skipped (exact), and so are the ground's details
(patches, stains, joints, shadows: the `detail` materials) in chunks beyond the detail reach, where they are
thinner than a pixel.

The polygons are filled by a compiled kernel (sim/render/raster_stereo.py) that follows cv2.fillPoly pixel for
pixel, or by OpenCV itself (compiled=False: the reference the kernel is held to).
"""
from __future__ import annotations

import cv2
import numpy as np

from sim.ground_painter import SUBPIXEL_BITS, GroundPainter
from sim.render.raster_stereo import paint_ground_pair


class StereoGroundPainter(GroundPainter):
    """`camera` is the rig's centre camera (eye_left = 0); `baseline` [m] between the two eyes; `materials` in
    painting order, of which `detail` are skipped in chunks not marked near."""

    def __init__(self, chunks, look, camera, materials, baseline: float, detail=()):
        super().__init__(chunks, look, camera, materials=materials)
        self.half = baseline / 2
        self._detail = np.array([m in detail for m in materials])
        self._tx = (camera.width / 2 + 1) / self._fx
        self._ty = (camera.height / 2 + 1) / self._fy
        self._has = np.array([len(t) > 0 for t in self._tables], dtype=bool)
        self._rgb = np.clip(np.array(self._colours, dtype=np.int64).reshape(-1, 3), 0, 255).astype(np.uint8)
        self._gathered: tuple[bytes, np.ndarray, np.ndarray, np.ndarray] | None = None

    def _gather(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(vertices, table, chunk per polygon) of chunks `idx`, kept while the same chunks are in view (most
        steps): the concatenation is the painter's, the same arrays in the same order."""
        key = idx.tobytes()
        if self._gathered is None or self._gathered[0] != key:
            chunks = idx.tolist()
            offsets = np.cumsum([0] + [len(self._verts[i]) for i in chunks])
            verts = np.concatenate([self._verts[i] for i in chunks])
            table = np.concatenate([self._tables[i] + [0, o, o] for i, o in zip(chunks, offsets[:-1])])
            owner = np.concatenate([np.full(len(self._tables[i]), i) for i in chunks])
            self._gathered = (key, verts, table, owner)
        return self._gathered[1:]

    def paint_pair(self, left: np.ndarray, right: np.ndarray, visible: np.ndarray, near_chunks: np.ndarray,
                   x: float, y: float, yaw: float, compiled: bool = True) -> int:
        """Paint the ground of the visible chunks (details only in the near ones) into both frames; returns the
        polygons painted."""
        idx = np.flatnonzero(visible & self._has)
        if not len(idx):
            return 0
        verts, table, owner = self._gather(idx)
        is_near = np.asarray(near_chunks, dtype=bool)[owner]
        eye, basis = self.camera.basis(x, y, yaw)
        cam = (verts - eye) @ basis.T
        if compiled:
            return paint_ground_pair(left, right, cam, table, is_near, self._detail, self._rgb, self.camera.near,
                                     self.half, self._tx, self._ty, self._fx, self._fy)
        return self._paint_opencv(left, right, cam, table, is_near)

    def _paint_opencv(self, left: np.ndarray, right: np.ndarray, cam: np.ndarray, table: np.ndarray,
                      is_near: np.ndarray) -> int:
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
