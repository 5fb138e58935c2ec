"""Seeded appearance of the sidewalk world: the colours of path, kerbs, grass, bushes, trees and obstacles, the
sky, the time of day and the sun (direction and brightness). MultiNet's data covers parks, sidewalks and forests
at different times of day and in different weather; the seed draws one such condition.

The colours are stored already tinted by the light's colour; shading (ambient + diffuse * cos) is applied by the
painters (sim/highway/scenery.py's Look.lit for the ground, sim/sidewalk/painter.py for objects).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.scene import Look

TIMES = ("morning", "noon", "afternoon", "evening", "overcast")
# elevation range [deg], light tint, sky top, sky at the horizon, ambient range, diffuse range
_TIME = {
    "morning": ((14, 30), (1.0, 0.94, 0.84), (0.42, 0.58, 0.85), (0.93, 0.87, 0.78), (0.42, 0.52), (0.45, 0.6)),
    "noon": ((50, 72), (1.0, 1.0, 0.98), (0.27, 0.48, 0.86), (0.72, 0.83, 0.95), (0.45, 0.55), (0.5, 0.62)),
    "afternoon": ((30, 50), (1.0, 0.97, 0.9), (0.33, 0.52, 0.84), (0.8, 0.85, 0.92), (0.45, 0.55), (0.48, 0.6)),
    "evening": ((8, 18), (1.0, 0.84, 0.66), (0.34, 0.4, 0.66), (0.98, 0.7, 0.48), (0.55, 0.65), (0.4, 0.55)),
    "overcast": ((55, 75), (0.93, 0.95, 0.98), (0.6, 0.63, 0.67), (0.84, 0.85, 0.86), (0.72, 0.8), (0.12, 0.2)),
}


@dataclass
class SidewalkLook(Look):
    time: str = "noon"
    style: str = "park"
    skyline: tuple = (0.2, 0.3, 0.2)     # colour of the distant treeline / buildings
    shadow_length: float = 0.0          # [m] of shadow per metre of height (0: no shadows, overcast)

    @property
    def sun_elevation(self) -> float:
        return math.asin(max(-1.0, min(1.0, self.light_direction[2])))

    def shadow_vector(self, height: float) -> np.ndarray:
        """World (dx, dy) [m] from an object's foot to the shadow of a point `height` [m] above it."""
        lx, ly, _ = self.light_direction
        n = math.hypot(lx, ly) or 1.0
        return -np.array([lx, ly]) / n * height * self.shadow_length

    def shade(self, rgb, normal) -> tuple[int, int, int]:
        """uint8 RGB of a face of colour rgb (0..1) facing `normal` (unit, world)."""
        k = self.ambient + self.diffuse * max(0.0, float(np.dot(normal, self.light_direction)))
        r, g, b = (int(v) for v in np.clip(np.asarray(rgb[:3]) * k * 255.0, 0, 255))
        return r, g, b


def _c(rgb, tint, scale: float = 1.0) -> tuple:
    return tuple(float(v) for v in np.clip(np.asarray(rgb) * tint * scale, 0, 1)) + (1.0,)


def make_look(seed: int, style: str, time: str | None = None) -> SidewalkLook:
    """The seed's look for a path of `style`: its time of day drawn from the seed, or the one `time` names (the
    same draws, the time's kept or overridden: a seed that draws that time looks the same either way)."""
    rng = np.random.default_rng([int(seed), 0x5EE])
    drawn = TIMES[int(rng.integers(len(TIMES)))]   # drawn whatever `time` says: the draws after it stay the seed's
    time = drawn if time is None else time
    (el0, el1), tint_rgb, sky_top, sky_hor, amb, dif = _TIME[time]
    tint = np.array(tint_rgb)
    az = rng.uniform(0, 2 * math.pi)
    el = math.radians(rng.uniform(el0, el1))
    light = (math.cos(az) * math.cos(el), math.sin(az) * math.cos(el), math.sin(el))
    ambient, diffuse = float(rng.uniform(*amb)), float(rng.uniform(*dif))
    dry = rng.uniform()
    if style == "forest":
        grass = np.array([0.22, 0.27, 0.13]) * rng.uniform(0.85, 1.15) + dry * np.array([0.12, 0.06, 0.02])
    else:
        grass = np.array([0.24 + 0.22 * dry, 0.46 + 0.04 * dry, 0.14 + 0.06 * dry]) * rng.uniform(0.85, 1.1)
    if style == "sidewalk":
        g = rng.uniform(0.58, 0.76)
        path = np.array([g, g * rng.uniform(0.97, 1.0), g * rng.uniform(0.92, 0.99)])
    elif style == "park":
        if rng.uniform() < 0.5:   # asphalt
            g = rng.uniform(0.3, 0.42)
            path = np.array([g, g, g * rng.uniform(1.0, 1.06)])
        else:                     # gravel
            path = np.array([0.66, 0.59, 0.47]) * rng.uniform(0.8, 1.1)
    else:                         # dirt
        path = np.array([0.45, 0.35, 0.24]) * rng.uniform(0.75, 1.15)
    bush = np.array([0.13, 0.33 + 0.1 * rng.uniform(), 0.12])
    colours = {
        "grass_dark": _c(grass, tint, 0.78), "grass_light": _c(grass * np.array([1.12, 1.2, 1.0]), tint, 1.1),
        "soil": _c(np.array([0.36, 0.28, 0.19]) * rng.uniform(0.8, 1.1), tint),
        "leaves": _c(np.array([0.55, 0.38, 0.16]) * rng.uniform(0.7, 1.1), tint),
        "kerb": _c(np.full(3, rng.uniform(0.72, 0.85)), tint), "kerb_face": _c(np.full(3, 0.5), tint),
        "path": _c(path, tint), "path_dark": _c(path, tint, 0.84), "path_light": _c(path, tint, 1.12),
        "joint": _c(path, tint, 0.72),
        "hedge": _c(np.array([0.1, 0.3, 0.1]) * rng.uniform(0.8, 1.2), tint),
        "bush_a": _c(bush, tint), "bush_b": _c(bush * np.array([1.5, 1.2, 0.9]), tint),
        "trunk": _c((0.33, 0.24, 0.16), tint), "foliage_a": _c((0.12, 0.34, 0.12), tint),
        "foliage_b": _c((0.26 + 0.15 * dry, 0.46, 0.13), tint), "conifer": _c((0.08, 0.25, 0.12), tint),
        "lamp": _c((0.25, 0.27, 0.28), tint),
        "cone": _c((0.95, 0.38, 0.05), tint), "stripe": _c((0.95, 0.95, 0.92), tint),
        "post": _c(np.array([0.55, 0.55, 0.55]) * rng.uniform(0.6, 1.2), tint),
        "wood": _c((0.52, 0.35, 0.2), tint), "metal": _c((0.18, 0.19, 0.2), tint),
        "bike": _c(rng.uniform(0.1, 0.9, 3), tint), "tyre": _c((0.06, 0.06, 0.06), tint),
        "shirt": _c(rng.uniform(0.1, 0.9, 3), tint), "trousers": _c(rng.uniform(0.05, 0.45, 3), tint),
        "skin": _c(np.array([0.85, 0.65, 0.5]) * rng.uniform(0.5, 1.05), tint),
        "lead": _c((0.1, 0.25, 0.8), tint), "lead_dark": _c((0.05, 0.05, 0.06), tint),
    }
    # a shadow is the ground lit by the ambient light alone; the ground painter lights flat ground by
    # (ambient + diffuse * sin(elevation)), so its colour is scaled down by the ratio
    flat = ambient + diffuse * max(0.0, light[2])
    k = ambient / flat
    colours["shadow_grass"] = _c(grass, tint, 0.9 * k)
    colours["shadow_path"] = _c(path, tint, k)
    skyline = np.array([0.16, 0.26, 0.17]) if style != "sidewalk" else \
        np.array([0.55, 0.52, 0.5]) * rng.uniform(0.6, 1.1)
    skyline = 0.6 * skyline * tint + 0.4 * np.array(sky_hor)   # aerial perspective: far things take the sky's tint
    shadow = 0.0 if time == "overcast" else min(4.0, 1.0 / math.tan(el))
    return SidewalkLook(colours, tuple(sky_top), tuple(sky_hor), tuple(grass * tint), light, ambient, diffuse,
                        time=time, style=style, skyline=tuple(skyline), shadow_length=shadow)
