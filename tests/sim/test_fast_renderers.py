"""The fast renderers (docs/rendering.md#the-fast-renderers) draw the frames PyBullet's TinyRenderer draws: on a fixed
set of scenes (every track preset and a procedural track, 1-4 lanes, cars near and far, ahead, behind and level with
the host, without insets, with the mirror and with the side views) each frame of "numba" and of "gl" agrees with
"tiny"'s within the tolerance the document states, and numba's ground is the OpenCV painter's pixel for pixel."""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from sim.camera import CameraConfig
from sim.ground_painter import GroundPainter
from sim.highway.renderer import Renderer
from sim.highway.scenery import GROUND_MATERIALS, build_scenery, make_look
from sim.highway.traffic import ScriptedTraffic
from sim.mirror import RearMirror, SideViews
from sim.render.available import renderer_problem
from sim.track import load_track
from sim.track.library import preset_names

# per renderer: the most a scene's frame may differ from tiny's, as the mean absolute difference over its pixels and
# channels [levels of 255] and as the share of its pixels that differ by more than 8 levels in a channel
TOLERANCE = {"numba": (0.05, 0.001), "gl": (1.5, 0.015)}
CLEAR = 8   # [levels] a difference a viewer sees


def scenes() -> list[tuple]:
    """(track, lanes, host s, host lane, inset, cars' s, cars' lanes, seed): three scenes a track, insets by turns."""
    out = []
    for i, name in enumerate(preset_names() + ["procedural:7"]):
        lanes = 1 + i % 4
        for k, share in enumerate((0.0, 0.37, 0.71)):
            ahead = [8.0, 25.0, 70.0, 140.0, -10.0, -30.0] + ([0.5] if lanes > 1 else [])
            car_lanes = [(k + j) % lanes for j in range(len(ahead))]
            if lanes > 1:
                car_lanes[-1] = (k + 1) % lanes   # level with the host, a lane over: in a side view
            out.append((name, lanes, share, k % lanes, ("", "mirror", "sides")[(i + k) % 3], ahead, car_lanes, 100 + i))
    return out


SCENES = scenes()


def frame(renderer: str, scene: tuple) -> np.ndarray:
    name, lanes, share, lane, inset, ahead, car_lanes, seed = scene
    track = load_track(name, lanes=lanes)
    s0 = share * track.length
    centres = track.lane_centres
    cars = ScriptedTraffic(track, [s0 + a for a in ahead], [float(centres[c]) for c in car_lanes],
                           [0.0] * len(ahead), seed=seed).states()
    x, y, yaw = (float(v) for v in track.pose(s0, float(centres[lane])))
    r = Renderer(track, seed, renderer=renderer, mirror=inset != "", sides=inset == "sides")
    try:
        return r.render(x, y, yaw, cars)
    finally:
        r.close()


# one scene a track, of every lane count and inset (the k-th scene of track i holds inset (i + k) % 3)
SAMPLE = [3 * i + i % 3 for i in range(len(SCENES) // 3)]


@functools.cache
def reference(i: int) -> np.ndarray:
    return frame("tiny", SCENES[i])


def test_the_scenes_cover_every_preset_every_lane_count_and_both_insets():
    for chosen in (SCENES, [SCENES[i] for i in SAMPLE]):
        assert {s[0] for s in chosen} >= set(preset_names())
        assert {s[1] for s in chosen} == {1, 2, 3, 4} and {s[4] for s in chosen} == {"", "mirror", "sides"}


def agree(renderer: str, indices) -> None:
    problem = renderer_problem(renderer)
    if problem:
        pytest.skip(problem)
    mean_limit, share_limit = TOLERANCE[renderer]
    worst = []
    for i in indices:
        out, ref = frame(renderer, SCENES[i]), reference(i)
        assert out.shape == ref.shape and out.dtype == np.uint8
        diff = np.abs(out.astype(np.int16) - ref.astype(np.int16))
        mean, share = float(diff.mean()), float((diff.max(axis=2) > CLEAR).mean())
        worst.append((mean, share, SCENES[i][:5]))
    assert max(w[0] for w in worst) <= mean_limit, max(worst)
    assert max(w[1] for w in worst) <= share_limit, max(worst, key=lambda w: w[1])


@pytest.mark.parametrize("renderer", sorted(TOLERANCE))
def test_frames_of_a_scene_a_track_agree_with_tinyrenderers_within_the_tolerance(renderer):
    agree(renderer, SAMPLE)


@pytest.mark.long
@pytest.mark.parametrize("renderer", sorted(TOLERANCE))
def test_frames_agree_with_tinyrenderers_within_the_tolerance(renderer):
    agree(renderer, range(len(SCENES)))


def test_numbas_ground_is_the_painters_pixel_for_pixel():
    """Ground alone (no objects, no cars), from the three kinds of camera, at poses off the lane centre and turned."""
    from sim.render.raster import Cars, Rasteriser  # numba: loaded here, not at collection
    rng = np.random.default_rng(5)
    empty = Cars(*(np.zeros(0) for _ in range(4)), np.zeros((0, 3)))
    for name in ("hairpins", "procedural:3"):
        track = load_track(name, lanes=3)
        chunks, look = build_scenery(track, 2), make_look(2)
        for chunk in chunks:
            chunk.objects = {}
        raster = Rasteriser(chunks, look, GROUND_MATERIALS, [])
        for camera in (CameraConfig(), RearMirror(210, 280).camera, SideViews(210, 280).camera,
                       CameraConfig(width=97, height=61, fov_deg=45.0)):
            painter = GroundPainter(chunks, look, camera, GROUND_MATERIALS)
            for _ in range(8):
                x, y, yaw = (float(v) for v in track.pose(rng.uniform(0, track.length), rng.uniform(-6, 6)))
                yaw += rng.uniform(-math.pi, math.pi)
                near = np.hypot(*(np.array([c.centre for c in chunks]) - (x, y)).T) < 230
                a = np.zeros((camera.height, camera.width, 3), np.uint8)
                b = a.copy()
                painter.paint(a, near, x, y, yaw)
                raster.draw(b, camera, x, y, yaw, near, empty)
                assert np.array_equal(a, b), (name, camera, x, y, yaw, int((a != b).any(axis=2).sum()))
