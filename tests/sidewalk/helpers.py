"""Shared set-ups of the sidewalk tests: a stadium-shaped path (two long straights), worlds with chosen obstacles
and borders, truth records made by hand."""
import math

import numpy as np

from core.worlds.sidewalk import SIDEWALK
from sim.sidewalk.layout import Border, make_obstacle
from sim.sidewalk.paths import load_path
from sim.sidewalk.world import SidewalkConfig, SidewalkWorld

STRAIGHT = 60.0   # [m]
RADIUS = 10.0     # [m]

# a car a network left squeezed between an obstacle (its left edge at 1.06 m) and the path's left edge (1.33 m),
# closing on the obstacle at 2.9 m/s: the recorded state of the MultiNet study's contact while the expert held the
# wheel (fields for record())
SQUEEZED = {"d": 1.186, "heading": -0.082, "speed": 2.88, "steer": 0.536, "path_width": 2.66,
            "curvature_ahead": 0.10, "border_left": 0.355, "obstacle_gap": 0.27, "obstacle_d": 0.885,
            "obstacle_width": 0.339}


def stadium(width: float = 2.0, name: str = "stadium") -> dict:
    return {"name": name, "style": "park", "width": width,
            "segments": [{"type": "straight", "length": STRAIGHT},
                         {"type": "arc", "radius": RADIUS, "angle_deg": 180, "turn": "left"},
                         {"type": "straight", "length": STRAIGHT},
                         {"type": "arc", "radius": RADIUS, "angle_deg": 180, "turn": "left"}]}


def world(obstacles=(), borders=None, seed: int = 0, mode: str = "direct", render: bool = False, start_s=5.0,
          **kw) -> SidewalkWorld:
    """A world on the stadium: `obstacles` as (kind, s, d, yaw) tuples; `borders` None (the seed's), or
    ((start, end, face), ...) for the left side and the same for the right side."""
    path = load_path(stadium())
    items = [make_obstacle(path, kind, s, d, yaw) for kind, s, d, yaw in obstacles]
    w = SidewalkWorld(SidewalkConfig(path=path, seed=seed, mode=mode, obstacles=items, render=render,
                                     start_s=start_s, **kw))
    if borders is not None:
        sides = []
        for sign, stretches in zip((1.0, -1.0), borders):
            b = Border(sign)
            for start, end, face in stretches:
                b.starts.append(start)
                b.ends.append(end)
                b.face.append(face)
                b.kinds.append("hedge")
                b.heights.append(0.8)
                b.depths.append(0.6)
            sides.append(b)
        w.layout.borders = tuple(sides)
    return w


def record(**fields) -> np.ndarray:
    """A truth record: the car at rest on the centre of a straight 2 m path, nothing around; `fields` override."""
    base = {n: 0.0 for n in SIDEWALK.truth_names}
    base.update(steer=0.5, motor=0.5, path_width=2.0, border_left=5.0, border_right=5.0, obstacle_gap=30.0,
                lead_gap=30.0)
    base.update(fields)
    return SIDEWALK.pack(base)


def angle(a: float) -> float:
    return math.remainder(a, 2 * math.pi)
