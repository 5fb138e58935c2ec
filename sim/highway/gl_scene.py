"""The highway's scene for the OpenGL renderer (sim/render/): the chunks' ground and roadside objects, the car
models and the frame's base image (backdrops, the insets' borders), and a view of it per camera.

The same scene as sim/highway/bullet_scene.py gives PyBullet and sim/ground_painter.py paints, from the same
chunks, colours and light; docs/rendering.md#the-fast-renderers says how closely the frames agree.
"""
from __future__ import annotations

import numpy as np

from sim.camera import CameraConfig
from sim.highway.car_models import PARTS, car_colours, car_models
from sim.highway.traffic import CarStates
from sim.render.gl_geometry import WIDTH, ground_rows, mesh_rows, outline_rows, ribbon_triangles
from sim.render.gl_programs import OBJECT, PAINTED
from sim.render.gl_scene import GLScene, Group
from sim.render.gl_views import View, camera_view
from sim.render.lighting import base_colour
from sim.scene import Chunk, Look


def chunk_group(chunk: Chunk, look: Look, materials: tuple[str, ...]) -> Group:
    """A chunk's ground (its materials in painting order, coloured as the painter colours them, and outlined) and
    its objects."""
    tris, lines = [np.zeros((0, WIDTH), np.float32)], [np.zeros((0, WIDTH), np.float32)]
    for rank, mat in enumerate(materials):
        colour = look.lit(look.colours[mat][:3])
        for poly in chunk.ground.get(mat, []):
            tris.append(ground_rows(ribbon_triangles(poly), rank, colour))
            lines.append(outline_rows(poly, rank, colour))
    for mat, mesh in chunk.objects.items():
        tris.append(mesh_rows(mesh.vertices, mesh.faces, mesh.normals, base_colour(look.colours[mat][:3]), OBJECT))
    return Group(np.concatenate(tris), np.concatenate(lines))


def model_rows(colours: dict) -> list[np.ndarray]:
    """Each car model's parts: the paint takes the instance's colour, the others their own (`colours`)."""
    out = []
    for m in car_models():
        parts = []
        for part in PARTS:
            mesh = m.parts[part]
            if part == "paint":
                parts.append(mesh_rows(mesh.vertices, mesh.faces, mesh.normals, (0, 0, 0), PAINTED))
            else:
                parts.append(mesh_rows(mesh.vertices, mesh.faces, mesh.normals,
                                       base_colour(colours[part][:3]), OBJECT))
        out.append(np.concatenate(parts))
    return out


class HighwayGL:
    def __init__(self, chunks: list[Chunk], look: Look, materials: tuple[str, ...], base: np.ndarray):
        """base: the frame before any view is drawn (the backdrops and the insets' borders)."""
        self.look = look
        self._n_models = len(car_models())
        paints, colours = car_colours(look.tint)
        self._paints = base_colour(paints)   # (n, 3) 0-255, as TinyRenderer holds each paint
        self._scene = GLScene([chunk_group(c, look, materials) for c in chunks], model_rows(colours), base,
                              look.light_direction, look.ambient, look.diffuse)

    def view(self, camera: CameraConfig, x: float, y: float, yaw: float, rect: tuple[int, int, int, int],
             groups: np.ndarray, cars: CarStates, car_visible: np.ndarray, mirrored: bool = False,
             keep: tuple[int, int, int, int] | None = None) -> View:
        """The view of `camera` from a host car at (x, y) [m] with yaw [rad] into `rect` of the frame, with the chunks
        `groups` and the cars `car_visible` in it."""
        on = np.flatnonzero(car_visible)
        models = np.asarray(cars.models, dtype=np.int64)[on]
        inst = np.empty((len(on), 7), dtype=np.float32)
        inst[:, 0], inst[:, 1] = cars.x[on], cars.y[on]
        inst[:, 2], inst[:, 3] = np.cos(cars.yaw[on]), np.sin(cars.yaw[on])
        inst[:, 4:7] = self._paints[np.asarray(cars.paints, dtype=np.int64)[on] % len(self._paints)]
        per_model = [inst[models == m] for m in range(self._n_models)]
        return camera_view(camera, x, y, yaw, rect, groups, per_model, mirrored, keep)

    def render(self, views: list[View], depth: np.ndarray | None = None) -> np.ndarray:
        """The frame of `views`; `depth`, when given, gets the objects' distances (sim/render/gl_scene.py)."""
        return self._scene.render(views, depth)

    def close(self) -> None:
        self._scene.release()
