"""What a named condition (core/conditions.py, docs/conditions.md) draws over a frame, whatever drew the frame.

A condition's colours and light (sky, ambient and diffuse light, the sun's direction, the road's colour) go into
the world's Look, which every renderer draws natively. What a renderer cannot draw (fog, darkness and the pools of
light in it, a wet road's sheen, rain streaks, the sun's glare, the lights of cars and lamps) is drawn here, after
the renderer, from the frame and its depth: the renderer's distances of the objects it drew, and the ground's,
which is a plane and known from each view's camera. So every renderer has every condition, the insets too, and the
same scene looks the same in each.

`Condition` holds a condition's drawn parameters; `Geometry` where each view of a frame (the front camera's, the
insets') is and what its pixels see; sim/render/effects.py draws a condition over the frames of a Geometry.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.camera import CameraConfig


@dataclass(frozen=True)
class Condition:
    """A named condition's parameters, drawn from a seed within the condition's ranges (the world's ranges: a
    sidewalk's fog is denser than a highway's). Angles [rad], distances [m], light levels relative to day."""

    name: str
    sun_elevation: float
    sun_azimuth: float
    visibility: float = math.inf        # [m] where the fog leaves 5 % of a far object's contrast (inf: no fog)
    fog_rgb: tuple = (0.8, 0.8, 0.8)
    tint: tuple = (1.0, 1.0, 1.0)       # the light's colour (low sun: warm), which the world's Look draws
    glare: float = 0.0                  # strength of the sun's glare when it is in view (0: none)
    night: float = -1.0                 # the light level away from any lamp (< 0: not night)
    headlight_reach: float = 0.0        # [m] where the host's low beams fall to half
    street_lights: float = 0.0          # strength of the street lamps' pools (0: unlit road)
    lamp_rgb: tuple = (1.0, 0.75, 0.45)
    wetness: float = 0.0                # how much a wet road mirrors (0: dry)
    rain: float = 0.0                   # streaks per 1000 pixels of frame (0: none)

    @property
    def density(self) -> float:
        """The fog's extinction per metre: 3 / visibility (a contrast of e^-3, 5 %, at the visibility)."""
        return 0.0 if math.isinf(self.visibility) else 3.0 / self.visibility

    @property
    def sun(self) -> np.ndarray:
        """Unit vector towards the sun in the world frame."""
        el, az = self.sun_elevation, self.sun_azimuth
        return np.array([math.cos(az) * math.cos(el), math.sin(az) * math.cos(el), math.sin(el)])

    @property
    def drawn(self) -> bool:
        """Whether anything is drawn over the renderer's frame (clear and overcast are their Look alone)."""
        return self.shades or self.glare > 0 or self.rain > 0

    @property
    def shades(self) -> bool:
        """Whether what the renderer drew changes with its distance (fog, darkness, a wet road): only then is its
        depth read back."""
        return self.density > 0 or self.night >= 0 or self.wetness > 0


@dataclass(frozen=True)
class Place:
    """A view of a frame: its camera, turned by `yaw` [rad] from the car's heading, drawn into `rect` (top, left,
    height, width [px]) of the frame, flipped left to right if `mirrored`."""

    camera: CameraConfig
    yaw: float
    rect: tuple[int, int, int, int]
    mirrored: bool = False


@dataclass(frozen=True)
class Lamps:
    """Street lamps: the centres (n, 2) [m, world] of their pools of light on the road, and their heads (n, 2) [m,
    world], `height` [m] up."""

    pools: np.ndarray
    heads: np.ndarray
    height: float


@dataclass(frozen=True)
class CarLights:
    """Every car model's tail lights and headlights: (models, 2, 3) [m] in its car's frame, and how strongly they
    glow (1: at night)."""

    tails: np.ndarray
    heads: np.ndarray
    strength: float


class Geometry:
    """Per pixel of a frame of `places` (later views drawn over earlier ones), what the effects read and that does
    not change from frame to frame: the view (-1: none, the insets' borders), the ray in the car frame (per metre
    along the view's axis) and the ground's distance along the view's axis (inf: the ray goes up, the sky); per
    view, its camera: a row of `cams`, its eye (3) [m, car frame], its right, up and forward unit vectors (9), focal
    lengths fx, fy [px], where its image is in the frame (top, left, height, width [px]), mirrored, near plane [m],
    horizontal field of view [rad], reach [m], 1 / fx and 1 / fy."""

    def __init__(self, shape: tuple[int, int], places: list[Place]):
        h, w = shape
        self.places = places
        self.view = np.full((h, w), -1, dtype=np.int8)
        self.rays = np.zeros((h, w, 3), dtype=np.float32)
        self.ground = np.full((h, w), np.inf, dtype=np.float32)
        self.eyes = np.zeros((len(places), 3), dtype=np.float32)
        self.horizons = np.zeros(len(places), dtype=np.int64)
        self.cams = np.zeros((len(places), 24))
        for v, p in enumerate(places):
            self._add(v, p)

    @property
    def ground_mask(self) -> np.ndarray:
        """(h, w) bool: the pixels of a view whose ray meets the ground."""
        return np.isfinite(self.ground) & (self.view >= 0)

    @property
    def lengths(self) -> np.ndarray:
        """(h, w): each ray's length (a metre along the view's axis is this far along the ray)."""
        return np.linalg.norm(self.rays, axis=2)

    def _add(self, v: int, p: Place) -> None:
        cam, (top, left, vh, vw) = p.camera, p.rect
        eye, basis = cam.basis(0.0, 0.0, p.yaw)   # the car at the origin, heading along x: the car frame
        f = 1.0 / math.tan(math.radians(cam.fov_deg) / 2)
        fx, fy = f / cam.aspect * cam.width / 2, f * cam.height / 2
        cols = np.arange(vw) + 0.5
        cols = cols[::-1] if p.mirrored else cols
        right = (cols - vw / 2) / fx
        up = (vh / 2 - (np.arange(vh) + 0.5)) / fy
        rays = right[None, :, None] * basis[0] + up[:, None, None] * basis[1] + basis[2]
        with np.errstate(divide="ignore"):
            ground = np.where(rays[..., 2] < 0, -eye[2] / rays[..., 2], np.inf)
        self.view[top:top + vh, left:left + vw] = v
        self.rays[top:top + vh, left:left + vw] = rays
        self.ground[top:top + vh, left:left + vw] = ground
        self.eyes[v] = eye
        self.horizons[v] = top + int(round(cam.horizon_row()))
        self.cams[v] = (*eye, *basis.reshape(-1), fx, fy, top, left, vh, vw, p.mirrored, cam.near, cam.hfov,
                        min(cam.far, cam.cull_distance), 1.0 / fx, 1.0 / fy)
