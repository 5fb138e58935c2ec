"""The PyBullet adapter: the only module that imports pybullet.

It turns the scenery's 3-D objects and the car models into bodies of a headless (DIRECT) client, hides
what is out of view (hidden bodies cost the TinyRenderer nothing) and renders the camera: colour, and a
mask of the pixels it drew, over which sim/highway/renderer.py composites the ground and the sky.
"""
from __future__ import annotations

import contextlib
import ctypes
import importlib.util
import math
import os
import shutil
import sys
import tempfile
import weakref
from pathlib import Path

import cv2
import numpy as np


@contextlib.contextmanager
def _quiet():
    """pybullet's C code prints banners on stdout and stderr; keep them out of our output."""
    sys.stdout.flush()
    sys.stderr.flush()
    libc = ctypes.CDLL(None)
    saved = [os.dup(1), os.dup(2)]
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    try:
        yield
    finally:
        libc.fflush(None)
        for fd, keep in ((1, saved[0]), (2, saved[1])):
            os.dup2(keep, fd)
            os.close(keep)
        os.close(devnull)


with _quiet():
    import pybullet as pb
    from pybullet_utils.bullet_client import BulletClient

from sim.camera import RENDERERS, CameraConfig  # noqa: E402  (below pybullet's quietened import, which must come first)
from sim.highway.car_models import PARTS, car_colours, car_models  # noqa: E402
from sim.highway.errors import RendererError  # noqa: E402
from sim.highway.mesh import MeshData  # noqa: E402
from sim.render.available import share_egl  # noqa: E402
from sim.scene import Chunk, Look  # noqa: E402


def _egl_plugin_file() -> str | None:
    """The file of pybullet's EGL renderer plugin, None when this build has none."""
    spec = importlib.util.find_spec("eglRenderer")
    return spec.origin if spec is not None else None


def egl_available() -> bool:
    return _egl_plugin_file() is not None


class _Held:
    """What a scene holds outside Python: its pybullet client, the EGL plugin, a temporary folder. Released once,
    by close() or else by a weakref.finalize: at garbage collection or, at the latest, at interpreter exit, before
    modules are torn down (pybullet's own BulletClient.__del__ would run after, and fail noisily)."""

    def __init__(self, bc):
        self.bc, self.plugin, self.tmp = bc, None, None

    def release(self) -> None:
        with _quiet():
            if self.plugin is not None and self.plugin >= 0:
                self.bc.unloadPlugin(self.plugin)
            self.bc.disconnect()
        if self.tmp is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)


class BulletScene:
    def __init__(self, chunks: list[Chunk], look: Look, camera: CameraConfig, renderer: str = "tiny"):
        if renderer not in RENDERERS:
            raise RendererError(f"unknown renderer '{renderer}' (choose from {', '.join(RENDERERS)})")
        self.camera, self.look, self.renderer = camera, look, renderer
        with _quiet():
            self._bc = BulletClient(connection_mode=pb.DIRECT)
        self._held = _Held(self._bc)
        self._finalizer = weakref.finalize(self, self._held.release)
        self._tmp: Path | None = None
        self._plugin = None
        if renderer == "egl":
            clash = share_egl("egl")
            if clash is not None:
                raise RendererError(clash)
            plugin_file = _egl_plugin_file()
            if plugin_file is None:
                raise RendererError("the EGL renderer plugin is not available in this pybullet build")
            with _quiet():
                self._plugin = self._held.plugin = self._bc.loadPlugin(plugin_file, "_eglRendererPlugin")
            if self._plugin < 0:
                raise RendererError("the EGL renderer plugin failed to load (no EGL driver?)")
            # the EGL plugin draws meshes from files only
            self._tmp = self._held.tmp = Path(tempfile.mkdtemp(prefix="drivestudio-egl-"))
        self._flag = pb.ER_BULLET_HARDWARE_OPENGL if renderer == "egl" else pb.ER_TINY_RENDERER
        self._projections = {camera: camera.projection_matrix()}
        self._n_shapes = 0
        self._frames = 0
        self.depth = np.zeros((0, 0), dtype=np.float32)   # the last frame's depth buffer (OpenGL's, 0-1)

        # static objects: one body per (chunk, material), all hidden until their chunk comes into view
        self._chunk_bodies: list[list[tuple[int, tuple]]] = []
        for chunk in chunks:
            bodies = []
            for mat, mesh in chunk.objects.items():
                rgba = tuple(look.colours[mat])
                shape = self._shape(mesh, rgba)
                body = self._bc.createMultiBody(baseVisualShapeIndex=shape)
                self._bc.changeVisualShape(body, -1, rgbaColor=rgba[:3] + (0.0,))
                bodies.append((body, rgba))
            self._chunk_bodies.append(bodies)
        self._chunk_visible = np.zeros(len(chunks), dtype=bool)

        # cars: shapes shared per model, bodies created per car slot on demand
        self._model_shapes = [{part: self._shape(m.parts[part], (1, 1, 1, 1)) for part in PARTS}
                              for m in car_models()]
        self._cars: list[dict] = []

    # --- construction helpers ---------------------------------------------------------------------------------
    def _shape(self, mesh: MeshData, rgba) -> int:
        if self._tmp is not None:
            path = self._tmp / f"m{self._n_shapes}.obj"
            self._n_shapes += 1
            mesh.to_trimesh().export(path, include_normals=True)
            return self._bc.createVisualShape(pb.GEOM_MESH, fileName=str(path), rgbaColor=rgba)
        return self._bc.createVisualShape(pb.GEOM_MESH, vertices=mesh.vertices.tolist(),
                                          indices=mesh.faces.reshape(-1).tolist(),
                                          normals=mesh.normals.tolist(), rgbaColor=rgba)

    def _new_car_body(self, model: int) -> int:
        shapes = self._model_shapes[model]
        links = [shapes[p] for p in PARTS[1:]]   # the base is the paint, the links the others
        k = len(links)
        return self._bc.createMultiBody(
            baseVisualShapeIndex=shapes["paint"], linkMasses=[0] * k, linkCollisionShapeIndices=[-1] * k,
            linkVisualShapeIndices=links, linkPositions=[[0, 0, 0]] * k, linkOrientations=[[0, 0, 0, 1]] * k,
            linkInertialFramePositions=[[0, 0, 0]] * k, linkInertialFrameOrientations=[[0, 0, 0, 1]] * k,
            linkParentIndices=[0] * k, linkJointTypes=[pb.JOINT_FIXED] * k, linkJointAxis=[[0, 0, 1]] * k)

    def _set_car_alpha(self, car: dict, alpha: float) -> None:
        paints, colours = car_colours(self.look.tint)
        paint = paints[car["paint"] % len(paints)]
        self._bc.changeVisualShape(car["body"], -1, rgbaColor=list(paint) + [alpha])
        for i, part in enumerate(PARTS[1:]):
            self._bc.changeVisualShape(car["body"], i, rgbaColor=list(colours[part][:3]) + [alpha])
        car["visible"] = alpha > 0

    # --- per frame ------------------------------------------------------------------------------------------------
    def set_cars(self, poses: np.ndarray, models, paints, visible) -> None:
        """Place the other cars: poses (n, 3) rows of x, y, yaw; models and paints index the catalogues;
        cars not `visible` are hidden. Car i keeps body slot i; a slot is rebuilt only when its model changes.
        """
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        n = len(poses)
        for i in range(n):
            model, paint = int(models[i]), int(paints[i])
            if i == len(self._cars):
                self._cars.append({"body": self._new_car_body(model), "model": model, "paint": paint,
                                   "visible": True})
                self._set_car_alpha(self._cars[i], 0.0)
            car = self._cars[i]
            if car["model"] != model:
                self._bc.removeBody(car["body"])
                car.update(body=self._new_car_body(model), model=model, visible=True)
                self._set_car_alpha(car, 0.0)
            if car["paint"] != paint:
                car["paint"] = paint
                self._set_car_alpha(car, 1.0 if car["visible"] else 0.0)
        for i, car in enumerate(self._cars):
            show = i < n and bool(visible[i])
            if show != car["visible"]:
                self._set_car_alpha(car, 1.0 if show else 0.0)
            if show:
                x, y, yaw = poses[i]
                self._bc.resetBasePositionAndOrientation(
                    car["body"], [x, y, 0.0], [0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])

    def set_visible_chunks(self, visible: np.ndarray) -> None:
        for i in np.flatnonzero(visible != self._chunk_visible):
            alpha = (1.0,) if visible[i] else (0.0,)
            for body, rgba in self._chunk_bodies[i]:
                self._bc.changeVisualShape(body, -1, rgbaColor=rgba[:3] + alpha)
        self._chunk_visible = visible.copy()

    def render(self, x: float, y: float, yaw: float, camera: CameraConfig | None = None) \
            -> tuple[np.ndarray, np.ndarray]:
        """Objects seen by `camera` (default: the scene's) from a host car at (x, y) [m] with yaw [rad]: (h, w, 3)
        uint8 RGB and an (h, w) uint8 mask, 1 where an object was drawn."""
        cam, look = camera or self.camera, self.look
        if cam not in self._projections:
            self._projections[cam] = cam.projection_matrix()
        # the EGL plugin announces its driver on the first frame
        with _quiet() if not self._frames and self._plugin is not None else contextlib.nullcontext():
            _, _, rgba, depth, _ = self._bc.getCameraImage(
                cam.width, cam.height, cam.view_matrix(x, y, yaw), self._projections[cam], renderer=self._flag,
                shadow=0, flags=pb.ER_NO_SEGMENTATION_MASK, lightDirection=list(look.light_direction),
                lightColor=[1.0, 1.0, 1.0], lightAmbientCoeff=look.ambient, lightDiffuseCoeff=look.diffuse,
                lightSpecularCoeff=0.0)
        self._frames += 1
        rgba = np.asarray(rgba, dtype=np.uint8).reshape(cam.height, cam.width, 4)
        rgb = cv2.cvtColor(rgba, cv2.COLOR_RGBA2RGB)  # numpy's strided copy is 10x slower here
        self.depth = np.asarray(depth, dtype=np.float32).reshape(cam.height, cam.width)
        drawn = self.depth < 0.999999
        return rgb, drawn.view(np.uint8)

    def close(self) -> None:
        self._finalizer()   # runs the release at most once
        self._bc = None
        self._tmp = None
