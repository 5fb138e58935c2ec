"""The stereo rig's geometry, measured on rendered frames: a thin post straight ahead shows the disparity the
documented geometry predicts, baseline * focal_px / depth, within a pixel."""
import math

import numpy as np
import pytest

from sim.sidewalk.car import CarState
from sim.sidewalk.stereo import BASELINE, EYE_FORWARD, FOV_DEG, PITCH_DEG, SIZE, StereoConfig
from tests.sidewalk.helpers import world


def test_the_documented_geometry():
    st = StereoConfig()
    assert (st.height, st.width) == SIZE == (188, 336)              # 2 x the network's 94 x 168
    assert st.baseline == BASELINE == pytest.approx(0.12)
    assert st.focal_px == pytest.approx(94 / math.tan(math.radians(FOV_DEG / 2)))
    assert st.hfov_deg == pytest.approx(87.1, abs=0.1)
    assert st.disparity(1.0) == pytest.approx(21.2, abs=0.05)


def post_columns(distance: float, row: int):
    """Columns of the post's centre in the left and right frames, at `row`: the frames with and without the post
    differ only where it (and its shadow, on the ground) is."""
    frames = []
    for obstacles in ([("post", 10.0 + EYE_FORWARD + distance, 0.0, 0.0)], []):
        w = world(obstacles=obstacles, borders=((), ()), start_s=10.0, render=True)
        w.car = CarState(s=10.0, d=0.0)
        frames.append(w.observe().frames)
    centres = []
    for with_post, without in zip(*frames):
        cols = np.flatnonzero(np.any(with_post[row] != without[row], axis=-1))
        assert len(cols) >= 2, "the post is not in the frame"
        assert cols.max() - cols.min() + 1 == len(cols), "one post, one run of pixels"
        centres.append((cols.min() + cols.max()) / 2)
    return centres


@pytest.mark.parametrize("distance", [1.5, 3.0, 6.0])
def test_a_post_straight_ahead_shows_the_predicted_disparity(distance):
    st = StereoConfig()
    cam = st.camera("left")
    row = int(cam.horizon_row())                 # the post's points at eye height project onto this row
    left, right = post_columns(distance, row)
    depth = distance * math.cos(math.radians(PITCH_DEG))   # along the optical axis, at eye height
    assert left - right == pytest.approx(st.disparity(depth), abs=1.0)
    cx = st.width / 2 - 0.5
    assert left > cx > right                      # straight ahead: right of centre in the left image
    assert (left - cx) == pytest.approx(cx - right, abs=1.0)   # and symmetrically in the right one
