import math

import numpy as np
import pytest

from sim.track import TrackError, load_track, preset_names, track_from_spec
from sim.track.procedural import procedural_spec

OVAL = {"name": "t-oval", "lanes": 3, "lane_width": 4.0, "segments": [
    {"type": "straight", "length": 400}, {"type": "arc", "radius": 120, "angle_deg": 180, "turn": "left"},
    {"type": "straight", "length": 400}, {"type": "arc", "radius": 120, "angle_deg": 180, "turn": "left"}]}


def test_first_segment_starts_at_origin_heading_plus_x():
    tr = track_from_spec(OVAL)
    assert tr.pose(0.0) == pytest.approx((0.0, 0.0, 0.0))
    assert tr.pose(100.0) == pytest.approx((100.0, 0.0, 0.0))
    assert tr.length == pytest.approx(800 + 2 * math.pi * 120)


def test_d_is_positive_to_the_left():
    tr = track_from_spec(OVAL)
    x, y, h = tr.pose(50.0, 3.0)
    assert (x, y) == pytest.approx((50.0, 3.0))  # heading +x: left is +y


def test_pose_on_a_left_arc():
    tr = track_from_spec(OVAL)
    s = 400 + math.pi / 2 * 120  # a quarter round the first arc: centre (400, 120)
    x, y, h = tr.pose(s)
    assert (x, y, h) == pytest.approx((520.0, 120.0, math.pi / 2))
    x, y, _ = tr.pose(s, 2.0)  # 2 m to the left = towards the centre
    assert (x, y) == pytest.approx((518.0, 120.0))
    assert tr.curvature(s) == pytest.approx(1 / 120)
    assert tr.curvature(10.0) == 0.0


def test_pose_on_a_right_arc():
    spec = {"name": "r", "lanes": 1, "segments": [
        {"type": "straight", "length": 100}, {"type": "arc", "radius": 60, "angle_deg": 180, "turn": "right"},
        {"type": "straight", "length": 100}, {"type": "arc", "radius": 60, "angle_deg": 180, "turn": "right"}]}
    tr = track_from_spec(spec)
    x, y, h = tr.pose(100 + math.pi / 2 * 60)  # centre (100, -60)
    assert (x, y, h) == pytest.approx((160.0, -60.0, -math.pi / 2))
    assert tr.curvature(120.0) == pytest.approx(-1 / 60)


@pytest.mark.parametrize("name", preset_names())
def test_frenet_inverts_pose_on_every_preset(name):
    tr = load_track(name)
    rng = np.random.default_rng(0)
    s = rng.uniform(0, tr.length, 300)
    d = rng.uniform(-tr.half_width - 2, tr.half_width + 2, 300)
    x, y, _ = tr.pose(s, d)
    s2, d2 = tr.frenet(x, y)
    assert np.abs(tr.gap(s, s2)).max() < 1e-6
    assert np.abs(d - d2).max() < 1e-6


def test_gap_wraps_into_half_loop():
    tr = track_from_spec(OVAL)
    assert tr.gap(tr.length - 10, 15) == pytest.approx(25.0)
    assert tr.gap(15, tr.length - 10) == pytest.approx(-25.0)


def test_lane_of_counts_from_the_left_and_clamps():
    tr = track_from_spec(OVAL)
    assert [tr.lane_of(d) for d in (5.9, 2.1, 1.9, -1.9, -2.1, -9.0, 9.0)] == [0, 0, 1, 1, 2, 2, 0]
    assert tr.markings.tolist() == [6, 2, -2, -6]
    assert tr.lane_centres.tolist() == [4, 0, -4]


@pytest.mark.parametrize("name", preset_names())
@pytest.mark.parametrize("lanes", [1, 2, 3])
def test_presets_are_valid_with_one_to_three_lanes(name, lanes):
    tr = load_track(name, lanes=lanes)
    assert tr.lanes == lanes
    dist, dh = tr.closure_error()
    assert dist <= 0.5 and dh <= 0.01


def test_at_least_six_presets():
    assert len(preset_names()) >= 6


def test_open_track_is_rejected():
    spec = dict(OVAL, segments=OVAL["segments"][:3])
    with pytest.raises(TrackError, match="does not close"):
        track_from_spec(spec)
    spec = dict(OVAL, segments=[dict(OVAL["segments"][0], length=400.6)] + OVAL["segments"][1:])
    with pytest.raises(TrackError, match="does not close"):
        track_from_spec(spec)
    spec = dict(OVAL, segments=[dict(OVAL["segments"][0], length=400.4)] + OVAL["segments"][1:])
    track_from_spec(spec)  # within 0.5 m


@pytest.mark.parametrize("bad, message", [
    ({"lanes": 5}, "lanes must be"), ({"lanes": 0}, "lanes must be"), ({"lane_width": 1.0}, "lane_width"),
    ({"segments": []}, "non-empty"), ({"segments": [{"type": "zigzag"}]}, "'type'"),
    ({"segments": [{"type": "straight", "length": -3}]}, "positive"),
    ({"segments": [{"type": "arc", "radius": 50, "angle_deg": 90, "turn": "up"}]}, "'turn'"),
])
def test_bad_fields_are_named(bad, message):
    with pytest.raises(TrackError, match=message):
        track_from_spec(dict(OVAL, **bad))


def test_too_tight_for_the_lane_count():
    spec = {"name": "tight", "segments": [
        {"type": "straight", "length": 100}, {"type": "arc", "radius": 15, "angle_deg": 180, "turn": "left"},
        {"type": "straight", "length": 100}, {"type": "arc", "radius": 15, "angle_deg": 180, "turn": "left"}]}
    track_from_spec(spec, lanes=1)
    with pytest.raises(TrackError, match="too tight"):
        track_from_spec(spec, lanes=3)


def test_self_crossing_is_rejected():
    # two full circles through the origin: the loop closes, but the second circle runs over the first
    spec = {"name": "double", "segments": [
        {"type": "arc", "radius": 50, "angle_deg": 360, "turn": "left"},
        {"type": "arc", "radius": 80, "angle_deg": 360, "turn": "left"}]}
    with pytest.raises(TrackError, match="runs into itself"):
        track_from_spec(spec, lanes=2)


def test_unknown_preset_and_missing_file():
    with pytest.raises(TrackError, match="unknown track preset 'nope'"):
        load_track("nope")
    with pytest.raises(TrackError, match="no such file"):
        load_track("/no/such/track.json")


def test_procedural_tracks_are_seeded_and_valid():
    a, b, c = procedural_spec(5), procedural_spec(5), procedural_spec(6)
    assert a == b and a != c
    for lanes in (1, 2, 3, 4):
        track_from_spec(a, lanes=lanes)
    assert load_track("procedural:5").length == pytest.approx(track_from_spec(a).length)


def test_straight_ahead():
    tr = track_from_spec(OVAL)
    assert tr.straight_ahead(100.0) == pytest.approx(300.0)
    assert tr.straight_ahead(500.0) == 0.0
