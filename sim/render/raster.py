"""The compiled rasteriser's scene (renderer "numba", docs/rendering.md#the-fast-renderers): a world's chunks
of ground and objects and its car models packed into arrays once, then one camera's view drawn into an image per
call. The ground is painted as sim/ground_painter.py paints it (sim/render/raster_ground.py), the objects drawn as
PyBullet's TinyRenderer draws them (sim/render/raster_objects.py), so the frames are those of renderer "tiny"
nearly pixel for pixel at a fraction of the time.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.camera import CameraConfig
from sim.render.lighting import base_colour
from sim.render.raster_ground import paint_ground
from sim.render.raster_objects import draw_bodies
from sim.scene import Chunk, Look


@dataclass
class Part:
    """A part of a model: a mesh (vertices (n, 3), faces (m, 3), unit vertex normals (n, 3)) and its colour (0-1);
    None: the paint of each car."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    rgb: tuple | None


@dataclass
class Cars:
    """The cars of one view, in the order they are drawn: pose and model, and the paint (0-1) of each."""

    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    models: np.ndarray
    paints: np.ndarray   # (n, 3)


def _triangles(parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]]):
    """Per face corner positions (t, 3, 3), normals (t, 3, 3), base colours (t, 3) and paint flags (t,) of meshes
    given as (vertices, faces, normals, base colour, painted)."""
    v, n, c, p = [np.zeros((0, 3, 3), np.float32)], [np.zeros((0, 3, 3), np.float32)], [np.zeros((0, 3), np.float32)], \
        [np.zeros(0, bool)]
    for verts, faces, normals, base, painted in parts:
        f = np.asarray(faces, dtype=np.int64)
        v.append(np.asarray(verts, dtype=np.float32)[f])
        n.append(np.asarray(normals, dtype=np.float32)[f])
        c.append(np.broadcast_to(np.asarray(base, dtype=np.float32), (len(f), 3)))
        p.append(np.full(len(f), painted))
    return (np.ascontiguousarray(np.concatenate(v)), np.ascontiguousarray(np.concatenate(n)),
            np.ascontiguousarray(np.concatenate(c)), np.concatenate(p))


def model_matrices(x: np.ndarray, y: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Cars' placements (n, 4, 4) as PyBullet makes them from the position (x, y, 0) and the quaternion of a turn by
    yaw about z, in double precision, then float32."""
    qz, qw = np.sin(np.asarray(yaw, dtype=np.float64) / 2), np.cos(np.asarray(yaw, dtype=np.float64) / 2)
    s = 2.0 / (qz * qz + qw * qw)
    zz, wz = qz * qz * s, qw * qz * s
    m = np.zeros((len(qz), 4, 4))
    m[:, 0, 0] = m[:, 1, 1] = 1.0 - zz
    m[:, 0, 1], m[:, 1, 0] = -wz, wz
    m[:, 0, 3], m[:, 1, 3] = x, y
    m[:, 2, 2] = m[:, 3, 3] = 1.0
    return m.astype(np.float32)


class Rasteriser:
    def __init__(self, chunks: list[Chunk], look: Look, materials: tuple[str, ...], models: list[list[Part]]):
        """materials: the ground materials in painting order."""
        self.look = look
        # ground polygons by (rank, chunk), each a span of one vertex array
        verts, spans, owner, n = [np.zeros((0, 3))], [], [], 0
        for ci, chunk in enumerate(chunks):
            for rank, mat in enumerate(materials):
                for poly in chunk.ground.get(mat, []):
                    verts.append(np.asarray(poly, dtype=np.float64))
                    spans.append((n, n + len(poly), rank))
                    owner.append((rank, ci))
                    n += len(poly)
        self._ground = np.ascontiguousarray(np.concatenate(verts))
        self._spans = np.array(spans, dtype=np.int64).reshape(-1, 3)
        self._owner = np.array(owner, dtype=np.int64).reshape(-1, 2)
        self._colours = np.array([look.lit(look.colours[m][:3]) for m in materials], dtype=np.int64).reshape(-1, 3)
        # objects: one body per chunk and per model, triangles of one array each
        bodies = [[(m.vertices, m.faces, m.normals, base_colour(look.colours[mat][:3]), False)
                   for mat, m in chunk.objects.items()] for chunk in chunks]
        bodies += [[(p.vertices, p.faces, p.normals, base_colour(p.rgb or (0.0, 0.0, 0.0)), p.rgb is None)
                    for p in parts] for parts in models]
        counts = []
        tris = []
        for body in bodies:
            t = _triangles(body)
            tris.append(t)
            counts.append(len(t[0]))
        self._v, self._n, self._c, self._p = (np.ascontiguousarray(np.concatenate([t[i] for t in tris]))
                                              for i in range(4))
        ends = np.cumsum(counts)
        self._first, self._end = ends - counts, ends
        self._n_chunks = len(chunks)
        self._light = np.asarray(look.light_direction, dtype=np.float32)
        self._ambient, self._diffuse = np.float32(look.ambient), np.float32(look.diffuse)
        self._identity = np.eye(4, dtype=np.float32)

    def draw(self, img: np.ndarray, camera: CameraConfig, x: float, y: float, yaw: float, chunks: np.ndarray,
             cars: Cars) -> None:
        """Paint the ground and draw the objects of the chunks `chunks` (bool, in view) and `cars` into img (h, w, 3)
        uint8 RGB, its backdrop, as `camera` sees them from a host car at (x, y) [m] with yaw [rad]."""
        polys = np.flatnonzero(chunks[self._owner[:, 1]])
        order = polys[np.lexsort((self._owner[polys, 1], self._owner[polys, 0]))]
        eye, basis = camera.basis(x, y, yaw)
        f = 1.0 / math.tan(math.radians(camera.fov_deg) / 2)
        fx, fy = f / camera.aspect * camera.width / 2, f * camera.height / 2
        if len(order):
            paint_ground(img, self._ground, self._spans, order, self._colours, eye, basis, camera.near, fx, fy)
        view = np.array(camera.view_matrix(x, y, yaw), dtype=np.float32).reshape(4, 4).T.copy()
        projection = np.array(camera.projection_matrix(), dtype=np.float32).reshape(4, 4).T.copy()
        # the chunks in view, then the cars: the order in which PyBullet's bodies were made, later ones winning ties
        on = np.flatnonzero(chunks)
        n = len(cars.x)
        bodies = np.concatenate([on, self._n_chunks + np.asarray(cars.models, dtype=np.int64)])
        firsts, ends = self._first[bodies], self._end[bodies]
        models = np.concatenate([np.broadcast_to(self._identity, (len(on), 4, 4)),
                                 model_matrices(cars.x, cars.y, cars.yaw)])
        paints = np.zeros((len(on) + n, 3), dtype=np.float32)
        paints[len(on):] = base_colour(cars.paints).reshape(-1, 3)
        zbuf = np.full(img.shape[:2], -np.inf, dtype=np.float32)
        draw_bodies(img, zbuf, self._v, self._n, self._c, self._p, firsts, ends, np.ascontiguousarray(models), paints,
                    view, projection, eye.astype(np.float32), self._light, self._ambient, self._diffuse)
