"""What any world's scenery is made of: chunks of ground polygons and objects along a track (cut so that a
renderer skips what is out of view), the sampling of the road along s, and the seeded Look (colours and light).
The highway's scenery (sim/highway/scenery.py) and the sidewalk's (sim/sidewalk/scenery.py) build on it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.track import Track

MAX_ARC_STEP = 0.05       # [rad] of turn between two road samples on an arc
MAX_ROAD_STEP = 4.0       # [m] between road samples: a long triangle that reaches behind the camera makes
                          # the TinyRenderer scan the whole screen for it


@dataclass
class Chunk:
    centre: np.ndarray                            # (2,) [m] world x, y
    radius: float                                 # [m] bounding circle of everything in it
    ground: dict = field(default_factory=dict)    # material -> list of (k, 3) polygons in the road plane
    objects: dict = field(default_factory=dict)   # material -> MeshData


@dataclass
class Look:
    """Seeded appearance: material colours (RGBA), sky, grass backdrop and the light."""

    colours: dict
    sky_top: tuple
    sky_horizon: tuple
    grass: tuple
    light_direction: tuple
    ambient: float
    diffuse: float
    tint: tuple | None = None   # the light's colour, for colours not held here (cars'); None: white, as always

    def lit(self, rgb) -> np.ndarray:
        """Colour the renderer gives a flat, upward-facing surface of colour rgb (0..1), as uint8 RGB."""
        k = self.ambient + self.diffuse * max(0.0, self.light_direction[2])
        return np.clip(np.asarray(rgb) * k * 255.0, 0, 255).astype(np.uint8)


def road_samples(track: Track, s0: float, s1: float) -> np.ndarray:
    """s values from s0 to s1 [m]: segment boundaries kept, at most MAX_ROAD_STEP apart, arcs cut every
    MAX_ARC_STEP of turn."""
    bounds = [b for b in track.starts if s0 < b < s1]
    knots = np.array([s0] + bounds + [s1])
    out = [knots[:1]]
    for a, b in zip(knots[:-1], knots[1:]):
        kappa = abs(track.curvature((a + b) / 2))
        n = max(1, int(math.ceil((b - a) * kappa / MAX_ARC_STEP)), int(math.ceil((b - a) / MAX_ROAD_STEP)))
        out.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(out)
