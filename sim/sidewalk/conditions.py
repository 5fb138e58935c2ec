"""The sidewalk in each named condition (docs/conditions.md): its times of day and weather under the highway's names.

The seeded look draws a time of day (sim/sidewalk/look.py); the named conditions choose one instead, with the seed's
palette: `clear` is noon, `overcast` the overcast sky, `low_sun` the evening (a low sun, warm light, long shadows,
which this world's painter draws). `night`, `fog` and `rain` are the overcast look with their sky, and what the
painters cannot draw is drawn over both images from their depth (sim/render/effects.py), at a 1/10-scale car's
distances: the fog is denser and the headlights shorter than the highway's.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from core.conditions import SEEDED, parameter_stream, pick
from sim.camera import CameraConfig
from sim.render.conditions import Condition, Geometry, Place
from sim.render.effects import Effects
from sim.sidewalk.look import SidewalkLook, make_look

TIME = {"clear": "noon", "overcast": "overcast", "low_sun": "evening"}   # the conditions that are times of day
CONDITION_OF_TIME = {"morning": "clear", "noon": "clear", "afternoon": "clear", "evening": "low_sun",
                     "overcast": "overcast"}   # what each seeded time of day is, by name
HEADLIGHT = (0.2, 0.12)   # [m] the car's lamps: ahead of its centre, above the ground
PATH_MATERIALS = ("path", "path_dark", "path_light", "joint", "shadow_path")


def condition_of(text: str, seed: int, style: str) -> Condition | None:
    """The condition a world configured with `text` (one name or a mix) is drawn in for `seed`; None: the seeded
    look, exactly as before conditions existed."""
    name = pick(text, seed)
    return None if name == SEEDED else draw_condition(name, seed, style)


def draw_condition(name: str, seed: int, style: str) -> Condition:
    """The parameters of condition `name` for `seed`, within the sidewalk's ranges."""
    look = make_look(seed, style, TIME.get(name, "overcast"))
    lx, ly, lz = look.light_direction
    c = Condition(name, math.asin(max(-1.0, min(1.0, lz))), math.atan2(ly, lx))
    rng = parameter_stream(name, seed)
    if name == "low_sun":
        return replace(c, glare=float(rng.uniform(0.4, 0.7)))
    if name == "night":
        return replace(c, night=float(rng.uniform(0.04, 0.08)), headlight_reach=float(rng.uniform(3.0, 6.0)))
    if name == "fog":
        grey = float(rng.uniform(0.72, 0.84))
        return replace(c, visibility=float(rng.uniform(6.0, 25.0)), fog_rgb=(grey, grey, min(1.0, grey * 1.02)))
    if name == "rain":
        return replace(c, visibility=float(rng.uniform(60.0, 120.0)), fog_rgb=(0.60, 0.62, 0.66),
                       wetness=float(rng.uniform(0.30, 0.50)), rain=float(rng.uniform(0.5, 1.2)))
    return c


def condition_look(seed: int, style: str, c: Condition) -> SidewalkLook:
    """The look the painters draw `c` with: the seed's palette at the condition's time of day and sky."""
    look = make_look(seed, style, TIME.get(c.name, "overcast"))
    if c.name in TIME:
        return look
    if c.name == "night":   # the painters draw the colours; the dark and the headlights are drawn over them
        return replace(look, time="night", sky_top=(0.012, 0.016, 0.035), sky_horizon=(0.04, 0.05, 0.09),
                       skyline=(0.02, 0.025, 0.03))
    if c.name == "fog":     # a white sky; the far treeline or houses gone in it
        return replace(look, time="fog", sky_top=c.fog_rgb, sky_horizon=c.fog_rgb, skyline=c.fog_rgb)
    colours = dict(look.colours)   # rain: the mist's sky, a darker wet path
    for m in PATH_MATERIALS:
        r, g, b, a = colours[m]
        colours[m] = (r * 0.6, g * 0.6, b * 0.6, a)
    skyline = tuple(0.5 * np.asarray(look.skyline) + 0.5 * np.asarray(c.fog_rgb))
    return replace(look, time="rain", sky_top=c.fog_rgb, sky_horizon=c.fog_rgb, skyline=skyline, colours=colours)


def eye_effects(c: Condition, look: SidewalkLook, camera: CameraConfig, seed: int) -> Effects:
    """What `c` draws over one camera's images: its fog, dark, headlights, wet path and rain."""
    geometry = Geometry((camera.height, camera.width), [Place(camera, 0.0, (0, 0, camera.height, camera.width))])
    return Effects(c, geometry, look.lit(look.colours["path"][:3]), seed, headlight=HEADLIGHT)
