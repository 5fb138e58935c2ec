"""The objects' rasteriser: flat-shaded convex pieces (sim/sidewalk/shapes.py) painted far to near with OpenCV.

Why not PyBullet's TinyRenderer, as the highway draws its objects: a 1/10-scale car's camera sits 0.24 m above
the ground, so the hedges and bushes a metre beside it fill much of the frame, and the TinyRenderer costs about
170 ns a covered pixel plus 1.7 ms a call at 336x188 (measured on this machine; docs/sidewalk.md): two such
frames a step could not reach the world's 150 stereo steps per second. OpenCV fills a convex polygon for about
1.2 microseconds whatever its size.

How: faces turned away from the eye are dropped (the pieces are closed and convex); the rest are moved into
camera space, clipped at the near plane, projected exactly as the ground painter projects the ground (the same
pinhole, the same fixed-point pixels) and filled piece by piece, the farthest piece first. Faces of one convex
piece never overlap on screen, so only pieces need ordering; pieces are ordered by the distance from the eye to
their centre, which is exact for pieces that do not interpenetrate and sit apart, as the scenery's do. Every
object stands on the ground and the ground is painted before, so no ground ever hides an object.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from sim.camera import CameraConfig

from .shapes import Piece

SUBPIXEL_BITS = 4


LOD_DISTANCE = 25.0    # [m] beyond this a piece with a simpler stand-in (bushes, crowns) is painted as that
MIN_PIXELS = 0.75      # a piece whose bounding sphere spans fewer pixels than this is not painted


class PieceSet:
    """Static pieces, grouped by chunk, with their faces' colours lit once (the light never moves). A piece may
    bring a simpler stand-in (Piece.far) painted beyond LOD_DISTANCE: level 0 faces always count, level 1 faces
    only near, level 2 faces only far."""

    def __init__(self, chunks: list[list[Piece]], look):
        faces, normals, colours, piece_of, centres, chunk_of, level = [], [], [], [], [], [], []
        radius, piece_chunk = [], []
        n_pieces = 0
        for c, pieces in enumerate(chunks):
            for p in pieces:
                versions = [(p, 0)] if p.far is None else [(p, 1), (p.far, 2)]
                for q, lv in versions:
                    faces.append(q.faces)
                    normals.append(q.normals)
                    colours.append(face_colours(q, look))
                    piece_of.append(np.full(len(q.faces), n_pieces))
                    chunk_of.append(np.full(len(q.faces), c))
                    level.append(np.full(len(q.faces), lv, np.int8))
                centres.append(p.centre)
                radius.append(float(np.linalg.norm(p.faces.reshape(-1, 3) - p.centre, axis=1).max()))
                piece_chunk.append(c)
                n_pieces += 1
        self.faces = np.concatenate(faces) if faces else np.zeros((0, 4, 3))
        self.normals = np.concatenate(normals) if normals else np.zeros((0, 3))
        self.colours = np.concatenate(colours) if colours else np.zeros((0, 3), np.uint8)
        self.piece = np.concatenate(piece_of) if piece_of else np.zeros(0, np.int64)
        self.centres = np.array(centres).reshape(-1, 3)
        self.chunk = np.concatenate(chunk_of) if chunk_of else np.zeros(0, np.int64)
        self.level = np.concatenate(level) if level else np.zeros(0, np.int8)
        self.radius = np.array(radius)                  # [m] per piece: its bounding sphere
        self.piece_chunk = np.array(piece_chunk, dtype=np.int64)
        self.first = self.faces[:, 0, :]
        # faces come chunk by chunk: chunk c's faces are [bounds[c], bounds[c + 1])
        self.bounds = np.searchsorted(self.chunk, np.arange(len(chunks) + 1))


def face_colours(p: Piece, look) -> np.ndarray:
    """(F, 3) uint8: the piece's colour lit by the look's light, per face."""
    base = np.asarray(look.colours[p.material][:3])
    k = look.ambient + look.diffuse * np.maximum(0.0, p.normals @ np.asarray(look.light_direction))
    if p.shades is not None:
        k = k * p.shades
    return np.clip(base[None, :] * k[:, None] * 255.0, 0, 255).astype(np.uint8)


class StereoObjectPainter:
    """Paints both images of a parallel stereo rig: `camera` is the rig's centre camera (eye_left = 0), the
    eyes sit +-baseline / 2 along its x axis (see sim/sidewalk/ground.py)."""

    def __init__(self, camera: CameraConfig, baseline: float, max_distance: float):
        self.camera = camera
        self.half = baseline / 2
        self.max_distance = max_distance
        f = 1.0 / math.tan(math.radians(camera.fov_deg) / 2)
        self._fx, self._fy = f / camera.aspect * camera.width / 2, f * camera.height / 2
        self._cx, self._cy = camera.width / 2 - 0.5, camera.height / 2 - 0.5

    def _pixels(self, cam: np.ndarray) -> np.ndarray:
        """Camera-space points (..., 3: right, up, forward) to cv2 fixed-point pixel coordinates."""
        scale = 1 << SUBPIXEL_BITS
        u = (cam[..., 0] / cam[..., 2] * self._fx + self._cx) * scale
        v = (-cam[..., 1] / cam[..., 2] * self._fy + self._cy) * scale
        return np.clip(np.stack([u, v], axis=-1), -2e8, 2e8).astype(np.int32)

    def _clip_near(self, poly: np.ndarray) -> np.ndarray:
        near = self.camera.near
        pts = poly.tolist()
        out = []
        for i, a in enumerate(pts):
            b = pts[i - len(pts) + 1]
            a_in, b_in = a[2] >= near, b[2] >= near
            if a_in:
                out.append(a)
            if a_in != b_in:
                t = (near - a[2]) / (b[2] - a[2])
                out.append([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), near])
        return np.array(out).reshape(-1, 3)

    def paint_pair(self, left: np.ndarray, right: np.ndarray, static: PieceSet, chunk_visible: np.ndarray, x: float,
                   y: float, yaw: float, dynamic: tuple | None = None) -> int:
        """Paint the visible static pieces and the `dynamic` ones ((faces, normals, colours, piece centres, piece
        index per face), e.g. the lead car) into both frames, for a car at (x, y, yaw). Returns the faces filled
        in the left frame."""
        eye, basis = self.camera.basis(x, y, yaw)
        side = basis[0]
        # pieces first: in a visible chunk, within reach, and at least MIN_PIXELS across; then their faces
        dist = np.linalg.norm(static.centres - eye, axis=1) if len(static.centres) else np.zeros(0)
        wanted = chunk_visible[static.piece_chunk] & (dist < self.max_distance) & \
            (static.radius * self._fy > MIN_PIXELS * dist)
        near_lod = dist < LOD_DISTANCE
        chunks = np.flatnonzero(chunk_visible)
        lo, hi = static.bounds[chunks], static.bounds[chunks + 1]
        idx = np.concatenate([np.arange(a, b) for a, b in zip(lo.tolist(), hi.tolist())]) if len(chunks) else \
            np.zeros(0, np.int64)
        piece, lv = static.piece[idx], static.level[idx]
        idx = idx[wanted[piece] & ((lv == 0) | ((lv == 1) & near_lod[piece]) | ((lv == 2) & ~near_lod[piece]))]
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
        facing = np.einsum("ij,ij->i", normals, eye - first)      # > 0: faces the centre eye
        across = normals @ side * self.half                       # how the test moves at either eye
        either = np.flatnonzero(facing + np.abs(across) > 0)      # faces one eye or the other
        faces, colours, piece, facing, across = faces[either], colours[either], piece[either], facing[either], \
            across[either]
        if not len(faces):
            return 0
        cam = (faces - eye) @ basis.T                     # (F, 4, 3) in the centre camera: right, up, forward
        z = cam[..., 2]
        near = self.camera.near
        zmax, zmin = z.max(axis=1), z.min(axis=1)
        order = np.lexsort((np.arange(len(piece)), -dist[piece]))   # far pieces first, stable within a piece
        w, h = self.camera.width << SUBPIXEL_BITS, self.camera.height << SUBPIXEL_BITS
        shift = np.array([self.half, 0.0, 0.0])
        n = 0
        for frame, sign in ((left, 1.0), (right, -1.0)):
            # the eye at eye_c - sign * half * side: n . (eye - p) changes by -sign * half * (n . side)
            front = (facing - sign * across > 0) & (zmax > near)
            idx = order[front[order]]
            c = cam[idx] + sign * shift
            with np.errstate(divide="ignore", invalid="ignore"):
                pix = self._pixels(c)
            whole = zmin[idx] >= near
            out = whole & ((pix[..., 0].max(axis=1) < 0) | (pix[..., 0].min(axis=1) > w) |
                           (pix[..., 1].max(axis=1) < 0) | (pix[..., 1].min(axis=1) > h))
            polys = list(pix)
            cols = colours[idx].tolist()
            for k in np.flatnonzero(~whole).tolist():   # the few faces that cross the near plane
                clipped = self._clip_near(c[k])
                polys[k] = self._pixels(clipped) if len(clipped) >= 3 else None
            fill, line = cv2.fillConvexPoly, cv2.LINE_8
            for poly, col, skip in zip(polys, cols, out.tolist()):
                if poly is not None and not skip:
                    fill(frame, poly, col, line, SUBPIXEL_BITS)
            if sign > 0:
                n = int(len(idx) - out.sum())
        return n
