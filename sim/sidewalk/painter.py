"""The objects' rasteriser: flat-shaded convex pieces (sim/sidewalk/shapes.py) painted far to near.

Why not PyBullet's TinyRenderer, as the highway draws its objects: a 1/10-scale car's camera sits 0.24 m above
the ground, so the hedges and bushes a metre beside it fill much of the frame, and the TinyRenderer costs about
170 ns a covered pixel plus 1.7 ms a call at 336x188 (measured on this machine; docs/sidewalk.md): two such
frames a step could not reach the world's 150 stereo steps per second. A convex polygon filled by its scan lines
costs about its pixels.

How: faces turned away from the eye are dropped (the pieces are closed and convex); the rest are moved into
camera space, clipped at the near plane, projected exactly as the ground painter projects the ground (the same
pinhole, the same fixed-point pixels) and filled piece by piece, the farthest piece first. Faces of one convex
piece never overlap on screen, so only pieces need ordering; pieces are ordered by the distance from the eye to
their centre, which is exact for pieces that do not interpenetrate and sit apart, as the scenery's do. Every
object stands on the ground and the ground is painted before, so no ground ever hides an object.

The numpy code here culls and moves the faces once for both eyes; a compiled kernel (sim/render/raster_stereo.py)
clips, projects and fills them as cv2.fillConvexPoly does, pixel for pixel, or OpenCV itself does (compiled=False:
the reference the kernel is held to).
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from sim.camera import CameraConfig
from sim.ground_painter import clip_near
from sim.render.raster_stereo import paint_objects_pair, select_faces
from sim.sidewalk.shapes import Piece

SUBPIXEL_BITS = 4


LOD_DISTANCE = 25.0    # [m] beyond this a piece with a simpler stand-in (bushes, crowns) is painted as that
MIN_PIXELS = 0.75      # a piece whose bounding sphere spans fewer pixels than this is not painted


class PieceSet:
    """Static pieces with their faces' colours lit once (the light never moves). A piece's faces are contiguous:
    piece i's are [start[i], start[i + 1]). A piece may bring a simpler stand-in (Piece.far) painted beyond
    LOD_DISTANCE: level 0 faces always count, level 1 faces only near, level 2 faces only far."""

    def __init__(self, chunks: list[list[Piece]], look):
        faces, normals, colours, level, centres, radius, piece_chunk, counts = [], [], [], [], [], [], [], []
        for c, pieces in enumerate(chunks):
            for p in pieces:
                n = 0
                for q, lv in ([(p, 0)] if p.far is None else [(p, 1), (p.far, 2)]):
                    faces.append(q.faces)
                    normals.append(q.normals)
                    colours.append(face_colours(q, look))
                    level.append(np.full(len(q.faces), lv, np.int8))
                    n += len(q.faces)
                counts.append(n)
                centres.append(p.centre)
                radius.append(float(np.linalg.norm(p.faces.reshape(-1, 3) - p.centre, axis=1).max()))
                piece_chunk.append(c)
        self.faces = np.concatenate(faces) if faces else np.zeros((0, 4, 3))
        self.normals = np.concatenate(normals) if normals else np.zeros((0, 3))
        self.colours = np.concatenate(colours) if colours else np.zeros((0, 3), np.uint8)
        self.level = np.concatenate(level) if level else np.zeros(0, np.int8)
        self.centres = np.array(centres).reshape(-1, 3)
        self.radius = np.array(radius)                  # [m] per piece: its bounding sphere
        self.piece_chunk = np.array(piece_chunk, dtype=np.int64)
        self.start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.piece = np.repeat(np.arange(len(counts)), counts)
        self.first = np.ascontiguousarray(self.faces[:, 0, :])

    def faces_of(self, pieces: np.ndarray) -> np.ndarray:
        """Indices of the faces of the given pieces (in piece order)."""
        lo, hi = self.start[pieces], self.start[pieces + 1]
        n = hi - lo
        total = int(n.sum())
        return np.repeat(lo - np.cumsum(n) + n, n) + np.arange(total)


def to_camera(points: np.ndarray, eye: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """World points (..., 3) in the camera at `eye` with rows (right, up, forward) `basis`: one matrix product of
    all of them (a stack of small ones costs four times as much, for the same numbers)."""
    return ((points - eye).reshape(-1, 3) @ basis.T).reshape(points.shape)


def face_colours(p: Piece, look) -> np.ndarray:
    """(F, 3) uint8: the piece's colour lit by the look's light, per face."""
    base = np.asarray(look.colours[p.material][:3])
    k = look.ambient + look.diffuse * np.maximum(0.0, p.normals @ np.asarray(look.light_direction))
    if p.shades is not None:
        k = k * p.shades
    return np.clip(base[None, :] * k[:, None] * 255.0, 0, 255).astype(np.uint8)


class StereoObjectPainter:
    """Paints both images of a parallel stereo rig: `camera` is the rig's centre camera (eye_left = 0), the
    eyes sit +-baseline / 2 along its x axis (see sim/sidewalk/ground.py).

    Culling, all exact (nothing visible is dropped) but for the size test: pieces whose bounding sphere lies
    outside the view frustum of both eyes, is beyond reach, or spans fewer than MIN_PIXELS; then faces turned
    away from both eyes, and faces wholly outside one plane of the frustum (the two sides, top, bottom, near)."""

    def __init__(self, camera: CameraConfig, baseline: float, max_distance: float):
        self.camera = camera
        self.half = baseline / 2
        self.max_distance = max_distance
        f = 1.0 / math.tan(math.radians(camera.fov_deg) / 2)
        self._fx, self._fy = f / camera.aspect * camera.width / 2, f * camera.height / 2
        self._cx, self._cy = camera.width / 2 - 0.5, camera.height / 2 - 0.5
        self._tx = (camera.width / 2 + 1) / self._fx     # tan of the half field of view, with a pixel to spare
        self._ty = (camera.height / 2 + 1) / self._fy
        self._view = (camera.near, self.half, self._tx, self._ty, self._fx, self._fy, self._cx, self._cy)
        slack = (math.sqrt(1 + self._tx * self._tx), math.sqrt(1 + self._ty * self._ty))
        self._limits = (camera.near, self.half, self._tx, self._ty, self._fy, max_distance, *slack, MIN_PIXELS,
                        LOD_DISTANCE)

    def _pixels(self, cam: np.ndarray) -> np.ndarray:
        """Camera-space points (..., 3: right, up, forward) to cv2 fixed-point pixel coordinates."""
        scale = 1 << SUBPIXEL_BITS
        u = (cam[..., 0] / cam[..., 2] * self._fx + self._cx) * scale
        v = (-cam[..., 1] / cam[..., 2] * self._fy + self._cy) * scale
        return np.clip(np.stack([u, v], axis=-1), -2e8, 2e8).astype(np.int32)

    def paint_pair(self, left: np.ndarray, right: np.ndarray, static: PieceSet, chunk_visible: np.ndarray, x: float,
                   y: float, yaw: float, dynamic: tuple | None = None, depths: tuple | None = None,
                   compiled: bool = True) -> int:
        """Paint the visible static pieces and the `dynamic` ones ((faces, normals, colours, piece centres, piece
        index per face), e.g. the lead car) into both frames, for a car at (x, y, yaw); `depths` (left, right)
        (h, w) float32, when given, get each painted face's distance along the camera's axis [m] where it is
        painted (its corners' mean: what a condition's fog and dark read). Returns the faces filled in the left
        frame."""
        eye, basis = self.camera.basis(x, y, yaw)
        if compiled:
            return self._paint_compiled(left, right, static, chunk_visible, eye, basis, dynamic, depths)
        idx, dist = self._static_faces(static, chunk_visible, eye, basis)
        faces, normals, colours = static.faces[idx], static.normals[idx], static.colours[idx]
        first, piece = static.first[idx], static.piece[idx]
        if dynamic is not None and len(dynamic[0]):
            d_faces, d_normals, d_colours, d_centres, d_piece = dynamic
            faces = np.concatenate([faces, d_faces])
            normals = np.concatenate([normals, d_normals])
            colours = np.concatenate([colours, d_colours])
            first = np.concatenate([first, d_faces[:, 0, :]])
            piece = np.concatenate([piece, d_piece + len(dist)])
            dist = np.concatenate([dist, np.linalg.norm(d_centres - eye, axis=1)])
        cam, colours, piece, facing, across = self._in_view(faces, normals, colours, first, piece, eye, basis)
        if not len(cam):
            return 0
        whole_all = cam[..., 2].min(axis=1) >= self.camera.near
        order = np.lexsort((np.arange(len(piece)), -dist[piece]))   # far pieces first, stable within a piece
        n = 0
        for frame, sign, depth in ((left, 1.0, None if depths is None else depths[0]),
                                   (right, -1.0, None if depths is None else depths[1])):
            filled = self._paint_eye(frame, sign, order, facing, across, cam, colours, whole_all, depth)
            if sign > 0:
                n = filled
        return n

    def _paint_compiled(self, left, right, static: PieceSet, chunk_visible, eye, basis, dynamic, depths) -> int:
        """paint_pair with the selection, the frustum test, the order, the clip and the fill of both eyes compiled:
        the same numbers from the same arithmetic, the arrays gathered once."""
        pc = (static.centres - eye) @ basis.T
        dist = np.linalg.norm(pc, axis=1)
        idx = select_faces(pc, dist, static.radius, static.piece_chunk, chunk_visible, static.start, static.level,
                           self._limits)
        normals, first, colours = static.normals.take(idx, 0), static.first.take(idx, 0), static.colours.take(idx, 0)
        piece, n_static = static.piece.take(idx), len(idx)
        if dynamic is not None and len(dynamic[0]):
            d_faces, d_normals, d_colours, d_centres, d_piece = dynamic
            normals = np.concatenate([normals, d_normals])
            colours = np.concatenate([colours, d_colours])
            first = np.concatenate([first, d_faces[:, 0, :]])
            piece = np.concatenate([piece, d_piece + len(dist)])
            dist = np.concatenate([dist, np.linalg.norm(d_centres - eye, axis=1)])
        facing, across, kept = self._facing_eyes(normals, first, eye, basis)
        if not len(kept):
            return 0
        ours = kept[kept < n_static]
        faces = static.faces.take(idx.take(ours), 0)
        if len(ours) < len(kept):
            faces = np.concatenate([faces, dynamic[0][kept[len(ours):] - n_static]])
        cam = to_camera(faces, eye, basis)
        zmean = cam[..., 2].mean(axis=1) if depths is not None else None
        dl, dr = (None, None) if depths is None else depths
        return paint_objects_pair(left, right, dl, dr, cam, kept, dist.take(piece), facing, across, colours, zmean,
                                  self._view)

    def _static_faces(self, static: PieceSet, chunk_visible: np.ndarray, eye: np.ndarray,
                      basis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The static faces to consider (indices into `static`, at the level of detail of their piece's distance)
        and every piece's distance from the eye. A piece counts when it is in a visible chunk, within reach, big
        enough, and its sphere is inside the frustum of an eye."""
        tx, ty, h = self._tx, self._ty, self.half
        pc = (static.centres - eye) @ basis.T
        dist = np.linalg.norm(pc, axis=1)
        r = static.radius
        wanted = chunk_visible[static.piece_chunk] & (dist < self.max_distance) & (r * self._fy > MIN_PIXELS * dist)
        wanted &= (pc[:, 2] + r > self.camera.near) & \
            (np.abs(pc[:, 0]) - h - pc[:, 2] * tx < r * math.sqrt(1 + tx * tx)) & \
            (np.abs(pc[:, 1]) - pc[:, 2] * ty < r * math.sqrt(1 + ty * ty))
        pieces = np.flatnonzero(wanted)
        idx = static.faces_of(pieces)
        piece, lv = static.piece[idx], static.level[idx]
        near_lod = dist[piece] < LOD_DISTANCE
        idx = idx[(lv == 0) | ((lv == 1) & near_lod) | ((lv == 2) & ~near_lod)]
        return idx, dist

    def _facing_eyes(self, normals: np.ndarray, first: np.ndarray, eye: np.ndarray, basis: np.ndarray) -> tuple:
        """(how much each face faces the centre eye, how that changes at either eye, the indices of those that
        face one eye or the other)."""
        facing = np.einsum("ij,ij->i", normals, eye - first)      # > 0: faces the centre eye
        across = normals @ basis[0] * self.half                   # how that changes at either eye
        return facing, across, np.flatnonzero(facing + np.abs(across) > 0)

    def _in_view(self, faces: np.ndarray, normals: np.ndarray, colours: np.ndarray, first: np.ndarray,
                 piece: np.ndarray, eye: np.ndarray, basis: np.ndarray) -> tuple:
        """The faces that face one eye or the other and are not wholly outside one plane of the frustum: (their
        corners in the centre camera, colours, pieces, how much they face the centre eye, how that changes at
        either eye)."""
        h, tx, ty = self.half, self._tx, self._ty
        facing, across, kept = self._facing_eyes(normals, first, eye, basis)
        cam = to_camera(faces[kept], eye, basis)                 # (F, 4, 3) in the centre camera: right, up, forward
        x_, y_, z_ = cam[..., 0], cam[..., 1], cam[..., 2]
        near = self.camera.near
        inside = (z_.max(axis=1) > near) & ((x_ - h - z_ * tx).min(axis=1) < 0) & \
            ((-x_ - h - z_ * tx).min(axis=1) < 0) & ((y_ - z_ * ty).min(axis=1) < 0) & \
            ((-y_ - z_ * ty).min(axis=1) < 0)
        sel = kept[inside]
        return cam[inside], colours[sel], piece[sel], facing[sel], across[sel]

    def _paint_eye(self, frame: np.ndarray, sign: float, order: np.ndarray, facing: np.ndarray,
                   across: np.ndarray, cam: np.ndarray, colours: np.ndarray, whole_all: np.ndarray,
                   depth: np.ndarray | None = None) -> int:
        """Fill the faces one eye sees (sign 1: left, -1: right), far pieces first, and their distances into
        `depth` when given; returns how many."""
        # the eye at eye_c - sign * half * side: n . (eye - p) changes by -sign * half * (n . side)
        idx = order[(facing - sign * across > 0)[order]]
        c = cam[idx] + sign * np.array([self.half, 0.0, 0.0])
        with np.errstate(divide="ignore", invalid="ignore"):
            pix = self._pixels(c)
        polys = list(pix)
        clip = np.flatnonzero(~whole_all[idx]).tolist()
        if clip:   # the few faces that cross the near plane: clipped, then projected together
            pieces_ = [clip_near(p, self.camera.near) for p in c[clip].tolist()]
            flat = [q for p in pieces_ for q in p]
            projected = self._pixels(np.array(flat).reshape(-1, 3)) if flat else np.zeros((0, 2), np.int32)
            at = 0
            for k, p in zip(clip, pieces_):
                polys[k] = projected[at:at + len(p)] if len(p) >= 3 else None
                at += len(p)
        fill, line = cv2.fillConvexPoly, cv2.LINE_8
        for poly, col in zip(polys, colours[idx].tolist()):
            if poly is not None:
                fill(frame, poly, col, line, SUBPIXEL_BITS)
        if depth is not None:
            for poly, z in zip(polys, c[..., 2].mean(axis=1).tolist()):
                if poly is not None:
                    fill(depth, poly, z, line, SUBPIXEL_BITS)
        return len(idx)
