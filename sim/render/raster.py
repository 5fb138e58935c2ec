"""The compiled rasteriser's scene (renderer "numba", docs/rendering.md#the-fast-renderers): a world's chunks of
ground and objects and its car models packed into arrays once, then one camera's view drawn into an image per call.
The ground is painted as sim/ground_painter.py paints it (sim/render/raster_ground.py), the objects drawn as
PyBullet's TinyRenderer draws them (sim/render/raster_objects.py), so the frames are those of renderer "tiny" pixel
for pixel but for a rare pixel at an edge, at a fraction of the time.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.camera import CameraConfig
from sim.render.lighting import base_colour
from sim.render.raster_view import draw_view
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
    """The cars of one view, in the order they are drawn: pose, model and paint (indices)."""

    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    models: np.ndarray
    paints: np.ndarray


def _triangles(meshes: list[tuple]) -> tuple[np.ndarray, ...]:
    """Per face corner positions (t, 3, 3), normals (t, 3, 3), base colours (t, 3) and paint flags (t,), float32, of
    meshes given as (vertices, faces, normals, base colour, painted)."""
    v: list[np.ndarray] = [np.zeros((0, 3, 3))]
    n: list[np.ndarray] = [np.zeros((0, 3, 3))]
    c: list[np.ndarray] = [np.zeros((0, 3))]
    p: list[np.ndarray] = [np.zeros(0, bool)]
    for verts, faces, normals, base, painted in meshes:
        f = np.asarray(faces, dtype=np.int64)
        v.append(np.asarray(verts, dtype=np.float32)[f])
        n.append(np.asarray(normals, dtype=np.float32)[f])
        c.append(np.broadcast_to(np.asarray(base, dtype=np.float32), (len(f), 3)))
        p.append(np.full(len(f), painted))
    return tuple(np.ascontiguousarray(np.concatenate(a), dtype=np.float32 if a is not p else bool)
                 for a in (v, n, c, p))


class Rasteriser:
    def __init__(self, chunks: list[Chunk], look: Look, materials: tuple[str, ...], models: list[list[Part]],
                 paints=()):
        """materials: the ground materials in painting order; paints: the colours (0-1) a car's paint may take."""
        self.look = look
        # ground polygons in painting order, by material and then by chunk: by_rank[rank, chunk] = (first, end)
        verts: list[np.ndarray] = [np.zeros((0, 3))]
        spans: list[tuple[int, int, int]] = []
        n = 0
        self._by_rank = np.zeros((len(materials), len(chunks), 2), dtype=np.int64)
        for rank, mat in enumerate(materials):
            for ci, chunk in enumerate(chunks):
                self._by_rank[rank, ci, 0] = len(spans)
                for poly in chunk.ground.get(mat, []):
                    verts.append(np.asarray(poly, dtype=np.float64))
                    spans.append((n, n + len(poly), rank))
                    n += len(poly)
                self._by_rank[rank, ci, 1] = len(spans)
        self._ground = np.ascontiguousarray(np.concatenate(verts))
        self._spans = np.array(spans, dtype=np.int64).reshape(-1, 3)
        self._colours = np.array([look.lit(look.colours[m][:3]) for m in materials], dtype=np.int64).reshape(-1, 3)
        # objects: one body per chunk, then one per model, the triangles of each a range of one array
        bodies = [[(m.vertices, m.faces, m.normals, base_colour(look.colours[mat][:3]), False)
                   for mat, m in chunk.objects.items()] for chunk in chunks]
        bodies += [[(p.vertices, p.faces, p.normals, base_colour(p.rgb or (0.0, 0.0, 0.0)), p.rgb is None)
                    for p in parts] for parts in models]
        tris = [_triangles(b) for b in bodies]
        self._v, self._n, self._c, self._p = (np.concatenate([t[i] for t in tris]) for i in range(4))
        counts = np.array([len(t[0]) for t in tris], dtype=np.int64)
        self._end = np.cumsum(counts)
        self._first = self._end - counts
        self._n_chunks = len(chunks)
        self._paints = base_colour(np.asarray(paints, dtype=np.float64).reshape(-1, 3))
        self._light = np.asarray(look.light_direction, dtype=np.float32)
        self._ambient, self._diffuse = np.float32(look.ambient), np.float32(look.diffuse)
        self._projections: dict[CameraConfig, tuple] = {}

    def _camera(self, camera: CameraConfig) -> tuple:
        """What a camera's views share: its projection (float32, as PyBullet takes it) and focal lengths [px]."""
        if camera not in self._projections:
            f = 1.0 / math.tan(math.radians(camera.fov_deg) / 2)
            self._projections[camera] = (
                np.array(camera.projection_matrix(), dtype=np.float32).reshape(4, 4).T.copy(),
                f / camera.aspect * camera.width / 2, f * camera.height / 2)
        return self._projections[camera]

    def draw(self, img: np.ndarray, camera: CameraConfig, x: float, y: float, yaw: float, chunks: np.ndarray,
             cars: Cars) -> None:
        """Paint the ground and draw the objects of the chunks `chunks` (bool, in view) and `cars` into img (h, w, 3)
        uint8 RGB, its backdrop, as `camera` sees them from a host car at (x, y) [m] with yaw [rad]."""
        projection, fx, fy = self._camera(camera)
        eye, basis = camera.basis(x, y, yaw)
        view = np.eye(4)   # OpenGL's lookAt, as CameraConfig.view_matrix makes it, in float32
        view[0, :3], view[1, :3], view[2, :3] = basis[0], basis[1], -basis[2]
        view[:3, 3] = -view[:3, :3] @ eye
        draw_view(img, np.ascontiguousarray(chunks, dtype=np.bool_), self._ground, self._spans, self._by_rank,
                  self._colours, eye, basis, camera.near, fx, fy, self._v, self._n, self._c, self._p, self._first,
                  self._end, self._n_chunks, view.astype(np.float32), projection,
                  np.asarray(cars.x, dtype=np.float64), np.asarray(cars.y, dtype=np.float64),
                  np.asarray(cars.yaw, dtype=np.float64), np.asarray(cars.models, dtype=np.int64),
                  self._paints[np.asarray(cars.paints, dtype=np.int64) % max(len(self._paints), 1)]
                  if len(cars.x) else np.zeros((0, 3), np.float32),
                  self._light, self._ambient, self._diffuse)
