"""The stereo pair's compiled kernels (sim/render/raster_stereo.py) draw OpenCV's pixels: a convex polygon is
cv2.fillConvexPoly's, colour and depth, wherever it lies; and the renderer's pairs are those of its OpenCV painters
byte for byte on a fixed set of scenes: every path preset and a procedural one, obstacles close before the car,
the car turned into the bushes and hedges of the borders, the lead car, every named condition, both eyes."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from core.conditions import CONDITIONS
from sim.render.raster_stereo import fill_convex
from sim.sidewalk.conditions import condition_of
from sim.sidewalk.paths import preset_names
from sim.sidewalk.stereo import StereoRenderer
from sim.sidewalk.world import SidewalkConfig, SidewalkWorld

H, W = 94, 168


def polygon(rng) -> np.ndarray:
    """A convex polygon's 3-5 corners (4-bit fixed point), either way round, in the image or reaching far out of it;
    now and then a corner repeated (the painter's triangles) or the whole polygon one point."""
    n = int(rng.integers(3, 6))
    scale = float(rng.choice([1.0, 1.0, 10.0, 300.0])) * rng.uniform(0.01, 1.0)
    p = (rng.uniform(-0.3, 1.3, (n, 2)) * [W, H] - [W / 2, H / 2]) * scale + [W / 2, H / 2]
    p = p[np.argsort(np.arctan2(*(p - p.mean(axis=0)).T[::-1]))]
    p = p[::-1] if rng.uniform() < 0.5 else p
    p = np.vstack([p, p[-1:]]) if rng.uniform() < 0.3 else p
    p = np.repeat(p[:1], len(p), axis=0) if rng.uniform() < 0.03 else p
    return np.clip(p * 16, -2e8, 2e8).astype(np.int32)


def test_a_convex_polygon_is_opencvs_in_colour_and_depth():
    rng = np.random.default_rng(48)
    for _ in range(1500):
        pts = polygon(rng)
        colour = tuple(int(c) for c in rng.integers(0, 256, 3))
        z = float(rng.uniform(0.0, 60.0))
        want, got = np.zeros((H, W, 3), np.uint8), np.zeros((H, W, 3), np.uint8)
        want_depth, got_depth = np.full((H, W), np.inf, np.float32), np.full((H, W), np.inf, np.float32)
        cv2.fillConvexPoly(want, pts, colour, cv2.LINE_8, 4)
        cv2.fillConvexPoly(want_depth, pts, z, cv2.LINE_8, 4)
        fill_convex(got, got_depth, pts.astype(np.int64), len(pts), *colour, z)
        assert np.array_equal(want, got) and np.array_equal(want_depth, got_depth), pts.tolist()


def poses(world: SidewalkWorld) -> list[tuple]:
    """(x, y, yaw) of the car: at its start (the lead car ahead in follow), close before obstacles, and turned into
    the borders a little inside the path's edge."""
    track, hw = world.path.track, world.path.half_width
    out = [tuple(float(v) for v in track.pose(world.layout.start_s, 0.0))]
    for i, o in enumerate(world.layout.obstacles[:3]):
        out.append(tuple(float(v) for v in track.pose(o.s - o.length / 2 - 0.35 - 0.2 * i, o.d)))
    for k, s in enumerate(np.linspace(5.0, world.path.length - 5.0, 4)):
        side = 1.0 if k % 2 else -1.0
        x, y, heading = track.pose(float(s), side * (hw - 0.1 - 0.05 * k))
        out.append((float(x), float(y), float(heading) + side * math.radians(35 + 12 * k)))
    return out


SCENES = [(path, "follow", "seeded") for path in preset_names() + ["procedural:11"]] + \
    [("park", "direct", name) for name in CONDITIONS[1:]]


@pytest.mark.parametrize("path, mode, condition", SCENES)
def test_the_compiled_pair_is_the_opencv_painters_byte_for_byte(path, mode, condition):
    world = SidewalkWorld(SidewalkConfig(path=path, seed=3, mode=mode, obstacles=8.0, render=False,
                                         condition=condition))
    look = condition_of(condition, world.seed, world.path.style)
    compiled = StereoRenderer(world.layout, world.seed, world.config.stereo, look)
    opencv = StereoRenderer(world.layout, world.seed, world.config.stereo, look, compiled=False)
    lead = world.lead.state if world.lead else None
    for x, y, yaw in poses(world)[: 4 if condition != "seeded" else None]:
        for got, want in zip(compiled.render(x, y, yaw, lead), opencv.render(x, y, yaw, lead)):
            assert np.array_equal(got, want), (x, y, yaw)
    assert compiled.faces_painted == opencv.faces_painted > 0
