"""The host car's camera image, composed in three layers (docs/rendering.md):

1. backdrop: sky above the horizon, open grass below (precomputed once);
2. ground: asphalt, verges, markings and grass patches, painted as exact projected polygons;
3. objects: cars, trees, poles, buildings, guard rails, every one standing on the ground, so in front of it.

How the layers are drawn is the world's `renderer` (sim/camera.py RENDERERS): "tiny" and "egl" paint the ground with
OpenCV (sim/ground_painter.py) and draw the objects with PyBullet (TinyRenderer or its EGL plugin), laid over wherever
PyBullet drew something; "numba" draws both layers with the compiled rasteriser (sim/render/raster.py), by the same
rules; "gl" draws every layer of every view with OpenGL (sim/render/gl_scene.py).

Chunks of scenery and cars outside the view wedge or beyond the cull distance are skipped. With a rear-view
mirror (sim/mirror.py) the same three layers are drawn a second time, small, from the mirror's rear camera, and
pasted into the top of the frame; with the side views, twice more from the side cameras, pasted below it.
"""
from __future__ import annotations

import cv2
import numpy as np

from sim.camera import DEFAULT_RENDERER, CameraConfig
from sim.ground_painter import GroundPainter
from sim.highway.car_models import PARTS, car_colours, car_models
from sim.highway.conditions import HighwayEffects, condition_look
from sim.highway.errors import RendererError
from sim.highway.scenery import GROUND_MATERIALS, Look, build_scenery, make_look
from sim.highway.traffic import CarStates
from sim.mirror import BORDER_RGB, RearMirror, SideViews, glass
from sim.render.available import share_egl
from sim.render.conditions import Condition, Place
from sim.track import Track

CAR_RADIUS = 3.0  # [m] bounding circle of a car, for culling


class Renderer:
    def __init__(self, track: Track, seed: int, camera: CameraConfig | None = None, renderer: str = DEFAULT_RENDERER,
                 mirror: bool = False, sides: bool = False, condition: Condition | None = None):
        """condition: a named condition's parameters (sim/highway/conditions.py), None: the seeded look."""
        self.camera = camera = camera or CameraConfig()
        self.look: Look = make_look(seed) if condition is None else condition_look(seed, condition)
        chunks = build_scenery(track, seed)
        self._centres = np.array([c.centre for c in chunks]).reshape(-1, 2)
        self._radii = np.array([c.radius for c in chunks])
        self.mirror = RearMirror(camera.height, camera.width) if mirror or sides else None   # sides need it
        self.sides = SideViews(camera.height, camera.width) if sides else None
        self.effects = None if condition is None or not condition.drawn else \
            HighwayEffects(condition, self.look, track, seed, (camera.height, camera.width), self._places())
        self._backdrops = {cam: self._make_backdrop(cam) for cam in self._cameras()}
        self._gl = self._raster = self._objects = None
        self._painters: dict[CameraConfig, GroundPainter] = {}
        if renderer == "gl":
            from sim.highway.gl_scene import HighwayGL  # lazy: moderngl and an OpenGL context, for this renderer only
            clash = share_egl("gl")
            if clash is not None:
                raise RendererError(clash)
            self._gl = HighwayGL(chunks, self.look, GROUND_MATERIALS, self._base_frame())
        elif renderer == "numba":
            from sim.render.raster import Part, Rasteriser, Slot  # lazy: numba loads (and compiles) for it only
            paints, colours = car_colours(self.look.tint)
            models = [[Part(m.parts[p].vertices, m.parts[p].faces, m.parts[p].normals,
                            None if p == "paint" else colours[p][:3]) for p in PARTS] for m in car_models()]
            self._raster = Rasteriser(chunks, self.look, GROUND_MATERIALS, models, paints)
            # every view of a frame in one compiled call, composed as render() composes PyBullet's
            slots = [Slot(camera, 0.0, self._backdrops[camera], (0, 0, camera.height, camera.width))]
            if self.mirror is not None:
                slots.append(Slot(self.mirror.camera, np.pi, self._backdrops[self.mirror.camera],
                                  glass(self.mirror.rect), self.mirror.rect, mirrored=True))
            if self.sides is not None:
                for rect, turn in zip(self.sides.rects, (np.pi / 2, -np.pi / 2)):
                    slots.append(Slot(self.sides.camera, turn, self._backdrops[self.sides.camera], glass(rect), rect))
            self._layout = self._raster.layout(slots, BORDER_RGB)
        else:
            from sim.highway.bullet_scene import BulletScene  # lazy: pybullet loads only when frames are wanted
            self._objects = BulletScene(chunks, self.look, camera, renderer)
            self._painters = {cam: GroundPainter(chunks, self.look, cam, GROUND_MATERIALS) for cam in self._cameras()}

    def _places(self) -> list[Place]:
        """Where each view goes in the frame: the front camera's, then the insets' glass."""
        cam = self.camera
        places = [Place(cam, 0.0, (0, 0, cam.height, cam.width))]
        if self.mirror is not None:
            places.append(Place(self.mirror.camera, np.pi, glass(self.mirror.rect), True))
        if self.sides is not None:
            places += [Place(self.sides.camera, turn, glass(rect))
                       for rect, turn in zip(self.sides.rects, (np.pi / 2, -np.pi / 2))]
        return places

    def _cameras(self) -> list[CameraConfig]:
        """The front camera and those of the insets."""
        return [self.camera] + ([self.mirror.camera] if self.mirror else []) + ([self.sides.camera] if self.sides
                                                                                   else [])

    def _make_backdrop(self, cam: CameraConfig) -> np.ndarray:
        look = self.look
        rows = np.arange(cam.height)[:, None] + 0.5
        horizon = cam.horizon_row()
        t = np.clip((horizon - rows) / max(horizon, 1.0), 0.0, 1.0)  # 0 at the horizon, 1 at the top row
        sky = (np.array(look.sky_horizon) * (1 - t) + np.array(look.sky_top) * t) * 255.0
        ground = np.broadcast_to(look.lit(look.grass).astype(np.float64), sky.shape)
        col = np.where(rows < horizon, sky, ground).astype(np.uint8)
        return np.ascontiguousarray(np.broadcast_to(col[:, None, :], (cam.height, cam.width, 3)))

    def _base_frame(self) -> np.ndarray:
        """The frame before any ground or object is drawn: every view's backdrop, the insets' borders."""
        frame = self._backdrops[self.camera].copy()
        if self.mirror is not None:
            self.mirror.composite(frame, self._backdrops[self.mirror.camera])
        if self.sides is not None:
            side = self._backdrops[self.sides.camera]
            self.sides.composite(frame, side, side)
        return frame

    def in_view(self, centres: np.ndarray, radii: np.ndarray, x: float, y: float, yaw: float,
                camera: CameraConfig | None = None) -> np.ndarray:
        """Which bounding circles (centres (n, 2), radii (n,) [m]) reach into the view wedge of `camera` (default:
        the front camera) looking along `yaw`."""
        camera = camera or self.camera
        v = centres - (x, y)
        dist = np.hypot(v[:, 0], v[:, 1])
        bearing = np.abs((np.arctan2(v[:, 1], v[:, 0]) - yaw + np.pi) % (2 * np.pi) - np.pi)
        margin = np.arcsin(np.clip(radii / np.maximum(dist, 1e-6), 0.0, 1.0))
        in_wedge = (dist <= radii) | (bearing <= camera.hfov / 2 + margin)
        return in_wedge & (dist - radii < camera.cull_distance)

    def render(self, x: float, y: float, yaw: float, cars: CarStates) -> np.ndarray:
        """(height, width, 3) uint8 RGB seen from a host car at (x, y) [m] with yaw [rad], the insets pasted in, the
        condition drawn over it."""
        if self.effects is None:
            return self._draw(x, y, yaw, cars, None)
        depth = np.empty((self.camera.height, self.camera.width), np.float32) if self.effects.needs_depth else None
        return self.effects.apply(self._draw(x, y, yaw, cars, depth), depth, x, y, yaw, cars)

    def _draw(self, x: float, y: float, yaw: float, cars: CarStates, depth: np.ndarray | None) -> np.ndarray:
        """The renderer's frame; `depth` (h, w), when given, gets the objects' distances along each view's axis [m]
        (inf where the renderer drew no object: the ground, the sky)."""
        if self._gl is not None:
            return self._gl.render(self._gl_views(x, y, yaw, cars), depth)
        if self._raster is not None:
            from sim.render.raster import Cars  # loaded with the rasteriser (above); this names its argument
            return self._raster.render(self._layout, x, y, yaw, Cars(cars.x, cars.y, cars.yaw, cars.models,
                                                                     cars.paints), CAR_RADIUS, depth)
        want = depth is not None
        frame, front = self._view(self.camera, x, y, yaw, cars, want)
        views = [front]
        if self.mirror is not None:
            rear, d = self._view(self.mirror.camera, x, y, yaw + np.pi, cars, want)
            self.mirror.composite(frame, rear)
            views.append(d)
        if self.sides is not None:
            cam = self.sides.camera
            left, dl = self._view(cam, x, y, yaw + np.pi / 2, cars, want)
            right, dr = self._view(cam, x, y, yaw - np.pi / 2, cars, want)
            self.sides.composite(frame, left, right)
            views += [dl, dr]
        if depth is not None:
            depth[:] = np.inf
            assert self.effects is not None
            for place, d in zip(self.effects.effects.geometry.places, views):
                assert d is not None
                top, left_, h, w = place.rect
                depth[top:top + h, left_:left_ + w] = d[:, ::-1] if place.mirrored else d
        return frame

    def _visible(self, camera: CameraConfig, x: float, y: float, yaw: float, cars: CarStates):
        """The chunks and the cars in the view wedge of `camera` (one test of both: a frame makes several)."""
        n = len(self._radii)
        centres = np.empty((n + len(cars), 2))
        centres[:n], centres[n:, 0], centres[n:, 1] = self._centres, cars.x, cars.y
        seen = self.in_view(centres, np.concatenate([self._radii, np.full(len(cars), CAR_RADIUS)]), x, y, yaw,
                            camera)
        return seen[:n], seen[n:]

    def _view(self, camera: CameraConfig, x: float, y: float, yaw: float, cars: CarStates,
              depth: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """One camera's image: backdrop, ground, then the objects in its view wedge; with `depth`, the objects'
        distances along its axis [m] (inf where none) too."""
        visible, car_visible = self._visible(camera, x, y, yaw, cars)
        frame = self._backdrops[camera].copy()
        assert self._objects is not None
        self._objects.set_visible_chunks(visible)
        self._objects.set_cars(np.stack([cars.x, cars.y, cars.yaw], axis=1), cars.models, cars.paints, car_visible)
        self._painters[camera].paint(frame, visible, x, y, yaw)
        rgb, drawn = self._objects.render(x, y, yaw, camera)
        cv2.copyTo(rgb, drawn, frame)
        if not depth:
            return frame, None
        window = self._objects.depth   # OpenGL's window depth, 0-1: near n and far f give f n / (f - d (f - n))
        n, f = camera.near, camera.far
        with np.errstate(divide="ignore"):
            return frame, np.where(drawn > 0, f * n / (f - window * (f - n)), np.inf).astype(np.float32)

    def _gl_views(self, x: float, y: float, yaw: float, cars: CarStates) -> list:
        """The views of the GL renderer, the insets first (each kept from the views after it), the front last."""
        gl = self._gl
        assert gl is not None

        def view(cam, heading, rect, mirrored=False, keep=None):
            groups, car_visible = self._visible(cam, x, y, heading, cars)
            return gl.view(cam, x, y, heading, rect, groups, cars, car_visible, mirrored, keep)

        views = []
        if self.mirror is not None:
            views.append(view(self.mirror.camera, yaw + np.pi, glass(self.mirror.rect), True,
                              self.mirror.rect))
        if self.sides is not None:
            for rect, turn in zip(self.sides.rects, (np.pi / 2, -np.pi / 2)):
                views.append(view(self.sides.camera, yaw + turn, glass(rect), keep=rect))
        views.append(view(self.camera, yaw, (0, 0, self.camera.height, self.camera.width)))
        return views

    def close(self) -> None:
        for part in (self._gl, self._objects):
            if part is not None:
                part.close()
