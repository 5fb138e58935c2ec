"""The stereo camera and the renderer of both its images.

The rig is ZED-like (MultiNet's cars carried a ZED): two identical pinhole cameras BASELINE apart, side by side
across the car, optical axes parallel, level across and pitched PITCH_DEG down, at EYE_HEIGHT above the ground.
A parallel rig is rectified by construction, so a point at depth Z [m] along the optical axis appears
focal_px * BASELINE / Z pixels further right in the left image than in the right one (its disparity), on the
same row. At the default 336x188 per camera (2x2-averaged, the network's 94x168):

    vertical field of view 56 deg, horizontal 2 * atan(tan(28 deg) * 336 / 188) = 87.1 deg
    focal length 94 / tan(28 deg) = 176.8 px (88.4 px at 168x94); disparity 21.2 px at 1 m, 4.2 px at 5 m

Each image is composed in three layers, as the highway's (sim/highway/renderer.py): the backdrop (sky gradient, a
distant skyline that turns with the car, the grass), the ground painted as exact projected polygons
(sim/ground_painter.py) and the objects painted far to near (sim/sidewalk/painter.py). Both images are drawn
together: the geometry is culled and moved into the rig's centre camera once, then compiled kernels
(sim/render/raster_stereo.py) fill each layer into both images as OpenCV's polygon fills would, byte for byte;
`compiled=False` draws with OpenCV itself, the reference they are held to (tests/sidewalk/test_stereo_kernels.py).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from sim.camera import CameraConfig
from sim.render.conditions import Condition
from sim.render.raster_stereo import draw_backdrop
from sim.sidewalk.conditions import condition_look, eye_effects
from sim.sidewalk.config import (  # noqa: F401  (the rig's constants and configuration, re-exported)
    BASELINE,
    CULL,
    EYE_FORWARD,
    EYE_HEIGHT,
    FOV_DEG,
    PITCH_DEG,
    SIZE,
    StereoConfig,
)
from sim.sidewalk.ground import StereoGroundPainter
from sim.sidewalk.layout import Layout
from sim.sidewalk.look import SidewalkLook, make_look
from sim.sidewalk.painter import PieceSet, StereoObjectPainter, face_colours
from sim.sidewalk.scenery import DETAIL, GROUND, GROUND_BASE, build_scenery, lead_pieces
from sim.sidewalk.shapes import concat

DEFAULT_RIG = StereoConfig()
PANORAMA = 1440           # columns of the skyline panorama (0.25 deg each)


def in_views(centres: np.ndarray, radii: np.ndarray, x: float, y: float, yaw: float, hfov: float,
             culls: tuple[float, ...]) -> tuple[np.ndarray, ...]:
    """Per depth of `culls` [m], which bounding circles reach into a view wedge of width hfov [rad] and that depth
    from (x, y, yaw)."""
    v = centres - (x, y)
    dist = np.hypot(v[:, 0], v[:, 1])
    bearing = np.abs((np.arctan2(v[:, 1], v[:, 0]) - yaw + np.pi) % (2 * np.pi) - np.pi)
    margin = np.arcsin(np.clip(radii / np.maximum(dist, 1e-6), 0.0, 1.0))
    wedge = (dist <= radii + 0.5) | (bearing <= hfov / 2 + margin)
    reach = dist - radii
    return tuple(wedge & (reach < cull) for cull in culls)


class StereoRenderer:
    def __init__(self, layout: Layout, seed: int, config: StereoConfig = DEFAULT_RIG,
                 condition: Condition | None = None, compiled: bool = True):
        """condition: a named condition's parameters (sim/sidewalk/conditions.py), None: the seeded look;
        compiled: the layers filled by the compiled kernels, else by OpenCV (the same pixels, slower)."""
        self.config = config
        self.compiled = compiled
        self.look: SidewalkLook = make_look(seed, layout.path.style) if condition is None else \
            condition_look(seed, layout.path.style, condition)
        chunks = build_scenery(layout, self.look)
        self._centres = np.array([c.ground.centre for c in chunks]).reshape(-1, 2)
        self._radii = np.array([c.ground.radius for c in chunks])
        self.cameras = {side: config.camera(side) for side in ("left", "right")}
        centre = config.camera("centre")
        detail = tuple(m for m in GROUND if m not in GROUND_BASE)
        self._ground = StereoGroundPainter([c.ground for c in chunks], self.look, centre, GROUND, config.baseline,
                                           detail)
        self._objects = StereoObjectPainter(centre, config.baseline, CULL)
        self._pieces = PieceSet([c.pieces for c in chunks], self.look)
        lead = lead_pieces()
        self._lead = (concat(lead), np.concatenate([face_colours(p, self.look) for p in lead]),
                      np.array([p.centre for p in lead]))
        index = self._lead[0][2]
        self._lead_base = np.array([self.look.colours["lead"][:3] if i < 1 else self.look.colours["lead_dark"][:3]
                                    for i in index])
        self._sky, self._pano, self._band = self._make_backdrop(self.cameras["left"], layout.seed)
        self._cols = {side: self._column_angles(cam) for side, cam in self.cameras.items()}
        self.faces_painted = 0
        self.effects = None if condition is None or not condition.drawn else \
            {side: eye_effects(condition, self.look, cam, seed) for side, cam in self.cameras.items()}

    # --- backdrop ----------------------------------------------------------------------------------------------
    def _make_backdrop(self, cam: CameraConfig, seed: int):
        """(static backdrop: sky gradient above the horizon, grass below; the skyline panorama (rows, PANORAMA,
        3); the rows it covers)."""
        look = self.look
        rows = np.arange(cam.height)[:, None] + 0.5
        horizon = cam.horizon_row()
        t = np.clip((horizon - rows) / max(horizon, 1.0), 0.0, 1.0)
        sky = (np.array(look.sky_horizon) * (1 - t) + np.array(look.sky_top) * t) * 255.0
        grass = np.broadcast_to(look.lit(look.grass).astype(np.float64), sky.shape)
        col = np.where(rows < horizon, sky, grass).astype(np.uint8)
        backdrop = np.ascontiguousarray(np.broadcast_to(col[:, None, :], (cam.height, cam.width, 3)))
        # the skyline: a silhouette of elevation angles around the full circle, far enough to show no disparity
        rng = np.random.default_rng([int(seed), 0x5C1])
        a = np.arange(PANORAMA) * 2 * math.pi / PANORAMA
        elev = np.zeros(PANORAMA)
        if look.style == "sidewalk":   # blocks of buildings
            i = 0
            while i < PANORAMA:
                w = int(rng.integers(20, 90))
                elev[i:i + w] = rng.uniform(0.03, 0.16)
                i += w + int(rng.integers(0, 25))
        else:                          # a treeline: a sum of bumps
            for k in range(1, 40):
                elev += rng.uniform(0, 0.012 / k ** 0.5) * np.sin(k * a + rng.uniform(0, 6.3))
            elev = np.clip(0.045 + elev + 0.02 * rng.random(PANORAMA) ** 3, 0.01, 0.2)
        f = cam.height / 2 / math.tan(math.radians(cam.fov_deg) / 2)
        top = int(max(0, math.floor(horizon - f * math.tan(elev.max()) - 2)))
        bottom = int(min(cam.height, math.ceil(horizon)))
        band_rows = np.arange(top, bottom) + 0.5
        # elevation of each band row's centre above the horizontal
        e = np.arctan((horizon - band_rows) / f)
        pano = np.where(e[:, None] < elev[None, :], 1.0, 0.0)[..., None]
        colour = np.array(look.skyline) * 255.0
        pano = (pano * colour + (1 - pano) * backdrop[top:bottom, :1, :].astype(np.float64)).astype(np.uint8)
        return backdrop, pano, (top, bottom)

    def _column_angles(self, cam: CameraConfig) -> np.ndarray:
        """Per image column, its bearing [rad] left of the optical axis."""
        f = cam.height / 2 / math.tan(math.radians(cam.fov_deg) / 2)
        u = np.arange(cam.width) + 0.5
        return np.arctan((cam.width / 2 - u) / f)

    # --- frames ------------------------------------------------------------------------------------------------
    def _lead_dynamic(self, lead):
        if lead is None:
            return None
        (faces, normals, index), colours, centres = self._lead
        c, s = math.cos(lead.yaw), math.sin(lead.yaw)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        off = np.array([lead.x, lead.y, 0.0])
        n = normals @ rot.T
        k = self.look.ambient + self.look.diffuse * np.maximum(0.0, n @ np.asarray(self.look.light_direction))
        lit = np.clip(self._lead_base * k[:, None] * 255.0, 0, 255).astype(np.uint8)
        return faces @ rot.T + off, n, lit, centres @ rot.T + off, index

    def _backdrop(self, side: str, yaw: float) -> np.ndarray:
        """One eye's backdrop: the sky and grass, the skyline's band turned to the car's heading."""
        columns = np.round((yaw + self._cols[side]) / (2 * math.pi) * PANORAMA).astype(np.int64) % PANORAMA
        if not self.compiled:
            frame = self._sky.copy()
            frame[self._band[0]:self._band[1]] = self._pano[:, columns]
            return frame
        frame = np.empty_like(self._sky)
        draw_backdrop(frame, self._sky, self._pano, self._band[0], columns)
        return frame

    def render(self, x: float, y: float, yaw: float, lead=None) -> tuple[np.ndarray, np.ndarray]:
        """(left, right) (h, w, 3) uint8 RGB seen from a car at (x, y) [m] with yaw [rad]; `lead` the lead car
        (x, y, yaw attributes) or None."""
        cam = self.cameras["left"]
        visible, near = in_views(self._centres, self._radii, x, y, yaw, cam.hfov + 0.2, (CULL, DETAIL))
        dynamic = self._lead_dynamic(lead)
        out = [self._backdrop(side, yaw) for side in ("left", "right")]
        self._ground.paint_pair(out[0], out[1], visible, near, x, y, yaw, self.compiled)
        if self.effects is None:
            self.faces_painted += self._objects.paint_pair(out[0], out[1], self._pieces, visible, x, y, yaw, dynamic,
                                                           compiled=self.compiled)
            return out[0], out[1]
        depths = tuple(np.full(cam.height * cam.width, np.inf, np.float32).reshape(cam.height, cam.width)
                       for _ in range(2)) if self.effects["left"].needs_depth else None
        self.faces_painted += self._objects.paint_pair(out[0], out[1], self._pieces, visible, x, y, yaw, dynamic,
                                                       depths, self.compiled)
        return self.effects["left"].apply(out[0], None if depths is None else depths[0], x, y, yaw), \
            self.effects["right"].apply(out[1], None if depths is None else depths[1], x, y, yaw)


def with_size(config: StereoConfig, width: int | None, height: int | None, fov: float | None) -> StereoConfig:
    return replace(config, width=config.width if width is None else width,
                   height=config.height if height is None else height,
                   fov_deg=config.fov_deg if fov is None else fov)
