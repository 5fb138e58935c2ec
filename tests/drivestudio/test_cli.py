"""probe and render as a user runs them, and their answer to bad input: one line on stderr, exit status 2."""
import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from core.worlds.highway import INDICATORS

EXAMPLES = Path(__file__).resolve().parents[2] / "docs" / "examples"


@pytest.fixture
def ds(run_cli):
    """The command in this process (tests/helpers.py); test_a_real_process_answers_as_in_process runs one for real."""
    return run_cli


def test_probe_prints_the_14_indicators_by_name(ds):
    r = ds("probe", EXAMPLES / "three-lane.json")
    assert r.returncode == 0, r.stderr
    v = json.loads(r.stdout)
    assert list(v) == list(INDICATORS)
    # ego d = -0.4 in the centre lane of three, heading 0.05: angle -0.05, ML = d - 2, MR = d + 2
    assert v["angle"] == pytest.approx(-0.05)
    assert (v["toMarking_ML"], v["toMarking_MR"]) == pytest.approx((-2.4, 1.6))
    assert (v["dist_LL"], v["dist_MM"], v["dist_RR"]) == pytest.approx((31.0, 18.0, 12.0))
    assert v["toMarking_M"] == 3.5 and v["fast"] == 1.0


def test_probe_on_a_users_own_track_file_and_all_labels(ds):
    r = ds("probe", EXAMPLES / "own-track.json", "--all")
    v = json.loads(r.stdout)
    assert v["lanes"] == 1 and v["lanes_left"] == 0 and v["dist_MM"] == pytest.approx(25.0)


def test_render_writes_a_280x210_frame_with_a_road(ds, tmp_path):
    out = tmp_path / "f.png"
    r = ds("render", EXAMPLES / "three-lane.json", "-o", out, "--truth", tmp_path / "f.json")
    assert r.returncode == 0, r.stderr
    img = cv2.imread(str(out))
    assert img.shape == (210, 280, 3)
    bottom = img[200:, 120:160].reshape(-1, 3).astype(int)
    assert np.all(np.abs(bottom[:, 0] - bottom[:, 2]) < 25)  # grey asphalt under the host car
    assert json.loads((tmp_path / "f.json").read_text())["lanes"] == 3


def test_a_car_ahead_shows_in_the_middle_of_the_frame(ds, tmp_path):
    base = {"track": "oval", "lanes": 3, "seed": 2, "ego": {"s": 100, "d": 0.0}}
    empty, one = tmp_path / "empty.json", tmp_path / "one.json"
    empty.write_text(json.dumps({**base, "cars": []}))
    one.write_text(json.dumps({**base, "cars": [{"s": 115, "d": 0.0}]}))
    assert ds("render", empty, "-o", tmp_path / "a.png").returncode == 0
    assert ds("render", one, "-o", tmp_path / "b.png").returncode == 0
    diff = np.abs(cv2.imread(str(tmp_path / "a.png")).astype(int) - cv2.imread(str(tmp_path / "b.png"))).sum(axis=2)
    ys, xs = np.nonzero(diff > 30)
    assert len(xs) > 200
    assert 110 < xs.mean() < 170            # straight ahead: the middle columns
    assert 80 < ys.mean() < 140             # on the road just below the horizon


def test_render_with_traffic_after_warm_up(ds, tmp_path):
    r = ds("render", "--track", "hairpins", "--lanes", "2", "--cars", "12", "--warmup", "5", "-o", tmp_path / "w.png")
    assert r.returncode == 0, r.stderr
    assert cv2.imread(str(tmp_path / "w.png")).shape == (210, 280, 3)


@pytest.mark.parametrize("content, message", [
    ("{not json", "malformed JSON at line 1"),
    ('{"track": "nowhere", "ego": {"s": 0, "d": 0}}', "unknown track preset 'nowhere'"),
    ('{"track": "oval", "lanes": 7, "ego": {"s": 0, "d": 0}}', "lanes must be an integer from 1 to 4"),
    ('{"track": "oval", "ego": {"s": 0, "d": 30}}', "ego: d = 30 m is off the road"),
    ('{"track": "oval", "ego": {"s": 0, "d": 0}, "cars": [{"s": 5, "d": -11}]}', "car 0: d = -11 m is off the road"),
    ('{"track": "oval", "ego": {"d": 0}}', "ego: missing 's'"),
    ('{"track": {"name": "open", "segments": [{"type": "straight", "length": 100}]}, "ego": {"s": 0, "d": 0}}',
     "track 'open' does not close"),
])
def test_bad_scenarios_get_one_line_and_status_2(ds, tmp_path, content, message):
    path = tmp_path / "bad.json"
    path.write_text(content)
    for verb in (["probe", path], ["render", path, "-o", tmp_path / "x.png"]):
        r = ds(*verb)
        assert r.returncode == 2, r.stderr
        assert message in r.stderr and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
        assert r.stdout == ""
    assert not (tmp_path / "x.png").exists()


def test_missing_file_and_bad_options(ds, tmp_path):
    r = ds("probe", tmp_path / "missing.json")
    assert r.returncode == 2 and "no such file" in r.stderr and r.stderr.count("\n") == 1
    r = ds("render", "--track", "oval", "--lanes", "9", "-o", tmp_path / "x.png")
    assert r.returncode == 2 and "argument --lanes: must be an integer from 1 to 4, got 9" in r.stderr
    r = ds("render", "--track", "oval", "--cars", "500", "-o", tmp_path / "x.png")
    assert r.returncode == 2 and "argument --cars: must be an integer from 0 to 300, got 500" in r.stderr
    r = ds("render")
    assert r.returncode == 2 and "required" in r.stderr and r.stderr.count("\n") == 1


def test_every_verb_has_help(ds):
    from drivestudio.cli import VERBS
    for verb in VERBS:
        r = ds(verb, "--help")
        assert r.returncode == 0 and "usage" in r.stdout, verb


def test_a_real_process_answers_as_in_process(ds, tmp_path):
    """The exit-status contract from a real interpreter: a probe's answer on stdout with 0, a scenario's refusal in
    one line with 2, --help with 0, byte for byte what the in-process runs above see."""
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    for argv in (["probe", EXAMPLES / "three-lane.json"], ["probe", bad], ["probe", "--help"]):
        real = subprocess.run([sys.executable, "-m", "drivestudio", *map(str, argv)], capture_output=True, text=True,
                              timeout=120)
        here = ds(*argv)
        assert (real.returncode, real.stdout, real.stderr) == (here.returncode, here.stdout, here.stderr), argv
    assert real.returncode == 0 and "usage" in real.stdout
