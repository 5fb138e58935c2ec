"""Box overlays: the geometry of the top-down view, the estimate's placement, PNGs and videos."""
import subprocess
import sys

import cv2
import numpy as np
import pytest

from core.worlds.highway import INDEX
from perception.highway.overlay import (
    CANVAS,
    GREEN,
    HOST_Y,
    PURPLE,
    PX_PER_M,
    RED,
    YELLOW,
    compose,
    draw_topdown,
    estimate_host,
    mean_normalised_error,
)
from sim.highway.truth import affordances
from sim.track import load_track


def centroid(img, colour):
    ys, xs = np.nonzero(np.all(img == colour, axis=2))
    return (xs.mean(), ys.mean(), len(xs)) if len(xs) else (None, None, 0)


def test_a_car_20_m_ahead_in_the_left_lane_lands_where_it_should():
    img = draw_topdown(lanes=3, lane_width=4.0, ego_s=100.0, ego_d=0.0, angle=0.0, cars=[(20.0, 4.0)], estimate=None)
    assert img.shape == (CANVAS[1], CANVAS[0], 3)
    x, y, n = centroid(img, YELLOW)
    assert n > 0
    assert x == pytest.approx(CANVAS[0] / 2 - 4.0 * PX_PER_M, abs=1.0)   # left of centre: 48 px for 4 m
    assert y == pytest.approx(HOST_Y - 20.0 * PX_PER_M, abs=1.0)         # 240 px above the host
    hx, hy, _ = centroid(img, RED)
    assert hx == pytest.approx(CANVAS[0] / 2, abs=1.0) and hy == pytest.approx(HOST_Y, abs=1.0)


def test_right_lane_and_behind_and_far_cars():
    img = draw_topdown(3, 4.0, 0.0, -4.0, 0.0, cars=[(-2.0, 0.0), (70.0, 0.0)], estimate=None)
    x, y, n = centroid(img, YELLOW)  # host in the right lane; a car 2 m behind in the centre lane
    assert x == pytest.approx(CANVAS[0] / 2, abs=1.0) and y == pytest.approx(HOST_Y + 24, abs=1.0)
    hx, _, _ = centroid(img, RED)
    assert hx == pytest.approx(CANVAS[0] / 2 + 48, abs=1.0)
    assert n < 2 * 29 * 57 * 0.8  # the car 70 m ahead (beyond the 60 m cap) is not drawn


def test_host_box_leans_left_when_the_car_is_turned_left():
    img = draw_topdown(3, 4.0, 0.0, 0.0, angle=-0.3, cars=[], estimate=None)
    ys, xs = np.nonzero(np.all(img == RED, axis=2))
    top = xs[ys < ys.mean()].mean()
    bottom = xs[ys > ys.mean()].mean()
    assert top < bottom  # the nose (top) is further left


@pytest.mark.parametrize("lanes", [1, 2, 3, 4])
def test_estimate_from_exact_indicators_puts_the_host_at_its_true_offset(lanes):
    tr = load_track("oval", lanes=lanes)
    for d in np.linspace(-tr.half_width - 1.9, tr.half_width + 1.9, 41):
        ind = affordances(tr, 100.0, float(d), 0.0, [120.0], [tr.lane_centres[0]])
        host = estimate_host(ind, lanes, 4.0, lanes_left=tr.lane_of(d), hint_d=float(d))
        assert host.system in ("in-lane", "on-marking", "both")
        assert host.d == pytest.approx(d, abs=1e-6), (lanes, d, host)


def test_estimate_system_and_ambiguity():
    tr = load_track("oval", lanes=3)
    both = estimate_host(affordances(tr, 100.0, 2.7, 0.0), 3, 4.0)
    assert both.system == "both" and both.d == pytest.approx(2.7)
    # on marking m_2 (between the centre and the right lane) only: the 13 indicators cannot say which
    # internal marking; the hint decides and the overlay says so
    ind = affordances(tr, 100.0, -2.2, 0.0)
    guess = estimate_host(ind, 3, 4.0, hint_d=-2.2)
    assert guess.system == "on-marking" and guess.lane_source == "ambiguous" and guess.d == pytest.approx(-2.2)
    told = estimate_host(ind, 3, 4.0, lanes_left=2)
    assert told.lane_source == "lanes_left" and told.d == pytest.approx(-2.2)


def test_near_inactive_estimates_count_as_inactive():
    # a network never hits an inactive value exactly: 3.41 for toMarking_M (inactive 3.5) is "off", so a car in
    # the middle of a 1-lane road is placed by its in-lane estimate alone, not on a marking 3.4 m away
    tr = load_track("oval", lanes=1)
    ind = affordances(tr, 100.0, 0.11, 0.0)
    noisy = ind.copy()
    for name, v in (("toMarking_L", -6.94), ("toMarking_M", 3.41), ("toMarking_R", 6.93),
                    ("toMarking_LL", -9.3), ("toMarking_RR", 9.4)):
        noisy[INDEX[name]] = v
    host = estimate_host(noisy, 1, 4.0)
    assert host.system == "in-lane" and host.d == pytest.approx(0.11)
    # and on a marking with a near-inactive in-lane system (ML -5.3, MR 5.2: a 10.5 m "lane")
    ind = affordances(tr, 100.0, -2.1, 0.0)  # just outside the right edge: on-marking only
    noisy = ind.copy()
    noisy[INDEX["toMarking_ML"]], noisy[INDEX["toMarking_MR"]] = -5.3, 5.2
    host = estimate_host(noisy, 1, 4.0)
    assert host.system == "on-marking" and host.d == pytest.approx(-2.1)


def test_a_one_lane_estimate_with_both_edges_present_still_picks_an_edge():
    tr = load_track("oval", lanes=1)
    ind = affordances(tr, 100.0, 2.3, 0.0)  # just outside the left edge: L inactive (-7), M about -0.3
    ind[INDEX["toMarking_L"]], ind[INDEX["toMarking_R"]] = -5.9, 5.0  # an untrained net's guesses
    host = estimate_host(ind, 1, 4.0)
    assert host.system == "on-marking" and host.d > 0  # the left edge, not a marking that does not exist


def test_estimated_cars_are_placed_by_the_gaps():
    tr = load_track("oval", lanes=3)
    ind = affordances(tr, 100.0, 0.0, 0.0, [130.0, 145.0, 200.0], [4.0, 0.0, -4.0])
    host = estimate_host(ind, 3, 4.0)
    assert sorted(host.cars) == [(30.0, 4.0), (45.0, 0.0)]  # the right lane's car is beyond 50 m


def test_compose_draws_truth_and_estimate():
    tr = load_track("oval", lanes=3)
    truth = affordances(tr, 100.0, 0.3, 0.05, [125.0], [4.0])
    est = truth.copy()
    est[INDEX["toMarking_ML"]] += 1.0
    est[INDEX["toMarking_MR"]] += 1.0
    est[INDEX["dist_LL"]] = 35.0
    frame = np.zeros((210, 280, 3), np.uint8)
    img = compose(frame, truth, est, 3, 4.0, 100.0, 0.3, [(25.0, 4.0)], title="t")
    assert img.shape == (660, 880, 3)
    top = img[:, :CANVAS[0]]
    gx, _, gn = centroid(top, GREEN)
    rx, _, rn = centroid(top, RED)
    assert gn > 0 and rn > 0 and gx < rx  # the estimate is 1 m further left than the truth
    assert centroid(top, PURPLE)[2] > 0 and centroid(top, YELLOW)[2] > 0
    assert mean_normalised_error(truth, est) > 0 and mean_normalised_error(truth, truth) == 0


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    from drivestudio.cli import main
    root = tmp_path_factory.mktemp("ov") / "ds"
    assert main(["generate", "--out", str(root), "--frames", "40", "--episode-frames", "20", "--tracks", "hairpins",
                 "--lanes", "2", "--cars", "6", "--workers", "1"]) == 0
    return root


def test_overlay_pngs_and_video_from_a_dataset(data, run_cli, tmp_path):
    r = run_cli("overlay", "--data", data, "--model", "oracle", "--split", "all", "--select", "random", "-n", "3",
                "--out", tmp_path / "png")
    assert r.returncode == 0, r.stderr
    pngs = sorted((tmp_path / "png").glob("overlay-*.png"))
    assert len(pngs) == 3 and cv2.imread(str(pngs[0])).shape == (660, 880, 3)
    video = tmp_path / "ep.mp4"
    r = run_cli("overlay", "--data", data, "--model", "oracle", "--split", "all", "--video", video, "--episode", "1")
    assert r.returncode == 0, r.stderr
    cap = cv2.VideoCapture(str(video))
    assert cap.get(cv2.CAP_PROP_FRAME_COUNT) == 20
    assert (cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT)) == (880, 660)


def test_drive_records_a_video(tmp_path):
    video = tmp_path / "run.mp4"
    subprocess.run([sys.executable, "-m", "drivestudio", "drive", "--model", "oracle", "--track", "oval", "--cars", "4",
                    "--seconds", "3", "--in-process", "--record", str(video), "--out", str(tmp_path)],
                   capture_output=True, text=True, check=True, timeout=120)
    cap = cv2.VideoCapture(str(video))
    assert cap.get(cv2.CAP_PROP_FRAME_COUNT) == 30 and cap.get(cv2.CAP_PROP_FRAME_WIDTH) == 880
    assert not list(tmp_path.glob(".*tmp*"))


def test_compose_draws_extra_rows_for_the_cars_beside_and_behind():
    """The rear labels get error-bar rows like the 13: a large error fills its bar red, a missing estimate none."""
    tr = load_track("oval", lanes=3)
    truth = affordances(tr, 100.0, 0.3, 0.05)
    frame = np.zeros((210, 280, 3), np.uint8)
    rows = [("dist_LB", 4.0, 30.0), ("dist_RB", 100.0, float("nan")), ("closing_LB", 2.0, 2.0),
            ("closing_RB", 0.0, float("nan"))]
    img = compose(frame, truth, truth.copy(), 3, 4.0, 100.0, 0.3, [], extra=rows)
    bars = img[420:, CANVAS[0]:]
    red = np.all(bars == (220, 40, 40), axis=-1)
    assert red.any() and not np.all(compose(frame, truth, truth.copy(), 3, 4.0, 100.0, 0.3, [])[420:, CANVAS[0]:]
                                    == (220, 40, 40), axis=-1).any()
    row = (240 - 22) / 17     # 13 rows and 4 extra: the red bar is the first extra row's
    ys = np.flatnonzero(red.any(axis=1))
    assert int(20 + 13 * row) <= ys.min() and ys.max() < int(20 + 14 * row) + 2
