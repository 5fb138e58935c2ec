"""Paths: presets and procedural loops close and keep to path-sized limits; bad path input is one PathError line."""
import json
import math

import numpy as np
import pytest

from sim.sidewalk.errors import PathError
from sim.sidewalk.paths import (
    LENGTH_RANGE,
    PROCEDURAL_LENGTH,
    WIDTH_RANGE,
    load_path,
    min_radius,
    path_from_spec,
    preset_names,
    procedural_spec,
)
from tests.sidewalk.helpers import stadium


def test_presets_are_closed_loops_of_path_size():
    assert set(preset_names()) >= {"park", "sidewalk", "forest"}
    for name in preset_names():
        p = load_path(name)
        dist, dh = p.track.closure_error()
        assert dist < 0.05 and dh < 0.01, name
        assert WIDTH_RANGE[0] <= p.width <= WIDTH_RANGE[1]
        assert 100.0 <= p.length <= 500.0, (name, p.length)
        assert p.track.min_radius() >= min_radius(p.width)


def test_procedural_loops_are_winding_closed_and_reproducible():
    for seed in range(6):
        spec = procedural_spec(seed)
        assert spec == procedural_spec(seed)                      # same seed, same path
        p = path_from_spec(spec)
        assert PROCEDURAL_LENGTH[0] <= p.length <= PROCEDURAL_LENGTH[1]
        turns = [s for s in spec["segments"] if s["type"] == "arc"]
        assert any(s["turn"] == "right" for s in turns), "a winding loop turns both ways"
        assert min(s["radius"] for s in turns) < 20.0              # radii of a few metres
        assert p.track.closure_error()[0] < 0.05
    assert procedural_spec(1) != procedural_spec(2)


def test_the_width_option_overrides_and_is_checked():
    assert load_path("park", width=2.8).width == 2.8
    for bad in (1.2, 3.5, float("nan")):
        with pytest.raises(PathError, match="width"):
            load_path("park", width=bad)


@pytest.mark.parametrize("change, message", [
    (lambda s: s["segments"].pop(), "does not close"),
    (lambda s: s.update(width=3.4), "'width' must be a number from 1.5 to 3"),
    (lambda s: s.update(width=1.0), "'width' must be a number from 1.5 to 3"),
    (lambda s: s["segments"][1].update(radius=2.0), "too tight"),
    (lambda s: s["segments"][0].update(length=float("nan")), "must be a positive number"),
    (lambda s: s.update(style="beach"), "'style' must be one of"),
    (lambda s: s.update(lanes=2), "unknown field 'lanes'"),
    (lambda s: s["segments"][1].update(turn="up"), "'turn' must be 'left' or 'right'"),
])
def test_bad_paths_are_refused_in_one_line(change, message):
    spec = stadium()
    change(spec)
    with pytest.raises(PathError, match=message) as e:
        path_from_spec(spec)
    assert "\n" not in str(e.value)


def test_a_loop_that_runs_into_itself_is_refused():
    def st(length):
        return {"type": "straight", "length": length}

    def arc(radius, angle, turn):
        return {"type": "arc", "radius": radius, "angle_deg": angle, "turn": turn}
    # a stadium whose lower straight makes a detour up to 2 m from the upper one
    detour = [st(20), arc(3, 90, "left"), st(12), arc(3, 90, "right"), st(2), arc(3, 90, "right"), st(12),
              arc(3, 90, "left"), st(26)]
    spec = {"name": "pinch", "style": "park", "width": 2.0,
            "segments": detour + [arc(10, 180, "left"), st(60), arc(10, 180, "left")]}
    with pytest.raises(PathError, match="runs into itself"):
        path_from_spec(spec)
    spec["segments"][2]["length"] = spec["segments"][6]["length"] = 8.0   # 6 m apart: allowed
    assert path_from_spec(spec).length > LENGTH_RANGE[0]


def test_path_files_are_read_strictly(tmp_path):
    good = tmp_path / "loop.json"
    good.write_text(json.dumps(stadium()))
    assert load_path(str(good)).length == pytest.approx(2 * 60 + 2 * math.pi * 10)
    for text, message in (('{"name": "x", "width": 2.0, "segments": [}', "malformed JSON"),
                          ('{"name": "x", "width": NaN, "segments": []}', "NaN is not allowed"),
                          ("", "empty")):
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        with pytest.raises(PathError, match=message) as e:
            load_path(str(bad))
        assert str(bad) in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(PathError, match="no such file"):
        load_path(str(tmp_path / "missing.json"))
    with pytest.raises(PathError, match="unknown path preset"):
        load_path("moon")
    with pytest.raises(PathError, match="procedural path must be an integer"):
        load_path("procedural:-3")


def test_track_geometry_is_the_highways():
    p = load_path(stadium())
    x, y, h = p.track.pose(60.0 + math.pi * 10 / 2, 1.0)   # the middle of the first bend, 1 m inside
    assert (x, y) == pytest.approx((60.0 + 9.0, 10.0))
    assert np.isclose(p.track.curvature(70.0), 0.1)
