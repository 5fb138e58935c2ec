"""The highway in each named condition (docs/conditions.md): the ranges a condition's parameters are drawn in, the
Look it gives the renderers, and the lights it draws over their frames (sim/render/conditions.py): the street lamps'
pools on the road, the cars' tail lights and headlights, the lamps themselves.

`clear` and `overcast` are the seeded look's two skies (sim/highway/scenery.py make_look) chosen instead of drawn:
a seed that draws a clear sky gives the same frames as `seeded` and `clear`.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from core.conditions import SEEDED, parameter_stream, pick
from sim.highway.car_models import car_models
from sim.highway.scenery import Look, light_poles, make_look
from sim.highway.traffic import CarStates
from sim.render.conditions import CarLights, Condition, Geometry, Lamps, Place
from sim.render.effects import Effects
from sim.track import Track

POLE_HEIGHT = 8.0      # [m] sim/highway/scenery.py's poles
LAMP_ARM = 1.8         # [m] the lamp hangs this far over the road from its pole
LAMP_REACH = 16.0      # [m] radius of a lamp's pool of light on the road
CAR_LIGHTS = {"night": 1.0, "fog": 0.7, "rain": 0.55}   # how strongly the cars' lights glow, by condition


def draw_condition(name: str, seed: int) -> Condition:
    """The parameters of condition `name` for `seed`, within the highway's ranges."""
    if name in ("clear", "overcast"):
        return _sun(Condition(name, 0.0, 0.0), make_look(seed, name))
    rng = parameter_stream(name, seed)
    if name == "low_sun":
        el, az = math.radians(rng.uniform(2.0, 10.0)), rng.uniform(0.0, 2 * math.pi)
        return Condition(name, el, az, tint=(1.0, float(rng.uniform(0.80, 0.88)), float(rng.uniform(0.58, 0.68))),
                         glare=float(rng.uniform(0.45, 0.8)))
    if name == "night":
        sodium = rng.uniform() < 0.5
        return Condition(name, math.radians(60.0), rng.uniform(0.0, 2 * math.pi),
                         night=float(rng.uniform(0.05, 0.10)), headlight_reach=float(rng.uniform(22.0, 32.0)),
                         street_lights=float(rng.uniform(0.35, 0.55)),
                         lamp_rgb=(1.0, 0.72, 0.40) if sodium else (0.92, 0.95, 1.0))
    if name == "fog":
        grey = float(rng.uniform(0.70, 0.82))
        return Condition(name, math.radians(60.0), 0.0, visibility=float(rng.uniform(40.0, 150.0)),
                         fog_rgb=(grey, grey, min(1.0, grey * 1.02)))
    if name == "rain":
        return Condition(name, math.radians(60.0), 0.0, visibility=float(rng.uniform(250.0, 500.0)),
                         fog_rgb=(0.60, 0.62, 0.66), wetness=float(rng.uniform(0.30, 0.50)),
                         rain=float(rng.uniform(0.5, 1.2)))
    raise ValueError(f"no condition {name!r}")


def condition_of(text: str, seed: int) -> Condition | None:
    """The condition a world configured with `text` (one name or a mix) is drawn in for `seed`; None: the seeded
    look, exactly as before conditions existed."""
    name = pick(text, seed)
    return None if name == SEEDED else draw_condition(name, seed)


def _sun(c: Condition, look: Look) -> Condition:
    lx, ly, lz = look.light_direction
    return replace(c, sun_elevation=math.asin(max(-1.0, min(1.0, lz))), sun_azimuth=math.atan2(ly, lx))


def condition_look(seed: int, c: Condition) -> Look:
    """The Look the renderers draw `c` with: the seed's palette, the condition's sky and light."""
    if c.name in ("clear", "overcast"):
        return make_look(seed, c.name)
    look = make_look(seed, "overcast")
    colours = dict(look.colours)
    if c.name == "low_sun":   # a low sun: warm light on everything, the cars' colours too (Look.tint)
        colours = {m: _tinted(rgba[:3], c) + tuple(rgba[3:]) for m, rgba in colours.items()}
        return replace(look, sky_top=_tinted((0.30, 0.40, 0.68), c), sky_horizon=_tinted((1.0, 0.80, 0.62), c),
                       grass=_tinted(look.grass, c), light_direction=tuple(c.sun), ambient=0.55, diffuse=0.65,
                       colours=colours, tint=tuple(c.tint))
    if c.name == "night":     # the renderers draw the scene's colours; the dark and the lights are drawn over it
        return replace(look, sky_top=(0.012, 0.016, 0.035), sky_horizon=(0.04, 0.05, 0.09),
                       light_direction=tuple(c.sun), ambient=0.85, diffuse=0.15)
    if c.name == "fog":       # a white sky, flat light
        return replace(look, sky_top=c.fog_rgb, sky_horizon=c.fog_rgb, ambient=0.80, diffuse=0.15)
    # rain: a grey sky (the mist's), flat light, a darker wet road and verges
    for name, k in (("asphalt", 0.55), ("verge", 0.80), ("patch_dark", 0.85), ("patch_light", 0.85)):
        r, g, b, a = colours[name]
        colours[name] = (r * k, g * k, b * k, a)
    return replace(look, sky_top=c.fog_rgb, sky_horizon=c.fog_rgb, ambient=0.62, diffuse=0.14,
                   grass=tuple(np.asarray(look.grass) * 0.9), colours=colours)


def _tinted(rgb, c: Condition) -> tuple:
    """A colour in the condition's light."""
    return tuple(float(a * b) for a, b in zip(rgb, c.tint))


def _model_lights() -> tuple[np.ndarray, np.ndarray]:
    """Every car model's tail lights and headlights: (models, 2, 3) centres [m] in the car's frame, left one first."""
    out = []
    for part in ("taillights", "headlights"):
        pairs = []
        for m in car_models():
            v = m.parts[part].vertices
            pairs.append([v[v[:, 1] > 0].mean(axis=0), v[v[:, 1] < 0].mean(axis=0)])
        out.append(np.array(pairs))
    return out[0], out[1]


class HighwayEffects:
    """A highway world's condition drawn over its frames of `places` (the front view and the insets): the street
    lamps of the scenery's light poles (none on some seeds: an unlit road) and the cars' lights."""

    def __init__(self, condition: Condition, look: Look, track: Track, seed: int, shape: tuple[int, int],
                 places: list[Place]):
        s, d = light_poles(track, seed)
        inward = -1.0 if d > 0 else 1.0   # from the pole towards the road
        heads = np.c_[track.pose(s, np.full_like(s, d + inward * LAMP_ARM))[:2]].reshape(-1, 2)
        pools = np.c_[track.pose(s, np.full_like(s, d + inward * (LAMP_ARM + 1.0)))[:2]].reshape(-1, 2)
        tails, fronts = _model_lights()
        self.effects = Effects(condition, Geometry(shape, places), look.lit(look.colours["asphalt"][:3]), seed,
                               lamps=Lamps(pools, heads, POLE_HEIGHT),
                               car_lights=CarLights(tails, fronts, CAR_LIGHTS.get(condition.name, 0.0)),
                               lamp_reach=LAMP_REACH)
        self.needs_depth = self.effects.needs_depth

    def apply(self, frame: np.ndarray, depth: np.ndarray | None, x: float, y: float, yaw: float,
              cars: CarStates) -> np.ndarray:
        """The frame with the condition drawn over it (a new array), seen from a host car at (x, y) [m] with yaw
        [rad]; depth: the objects' distances (sim/render/effects.py)."""
        return self.effects.apply(frame, depth, x, y, yaw, (np.asarray(cars.x, dtype=np.float64),
                                                             np.asarray(cars.y, dtype=np.float64),
                                                             np.asarray(cars.yaw, dtype=np.float64),
                                                             np.asarray(cars.models, dtype=np.int64)))
