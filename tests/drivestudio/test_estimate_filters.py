"""The Chen driver's optional filters of a model's estimates (docs/controller.md): exponential smoothing of every
indicator, the gap hold (a shorter gap is taken at once, a longer one approached with the factor) and the pass
memory (a neighbour car being passed carried on once lost)."""
from types import SimpleNamespace

import numpy as np
import pytest

from core.worlds.highway import HIGHWAY, INDICATORS
from drivestudio.driver_spec import DriverSpec
from drivestudio.worlds.highway.drivers import ESTIMATE, ChenDriver
from drivestudio.worlds.highway.filters import make_filters


class Scripted:
    """A predictor that returns the given indicator vectors in turn (the filters' arithmetic, not a model's)."""
    name, outputs, instants = "scripted", tuple(INDICATORS[:13]), (0,)

    def __init__(self, rows):
        self.rows = iter(rows)

    def __call__(self, frame):
        return np.asarray(next(self.rows), dtype=np.float64)


def _row(dist_mm, to_marking_m=0.5):
    v = dict.fromkeys(INDICATORS[:13], 10.0)
    v["dist_MM"], v["toMarking_M"] = dist_mm, to_marking_m
    return [v[n] for n in INDICATORS[:13]]


def _estimates(driver, n):
    record = HIGHWAY.pack({k: 0.0 for k in HIGHWAY.truth_names})
    record[HIGHWAY.index("speed")], record[HIGHWAY.index("lanes")] = 15.0, 2
    percept = SimpleNamespace(frames=(None,), record=record, t=0.0)
    return [driver.estimate(percept) for _ in range(n)]


MM, M = ESTIMATE.index("dist_MM"), ESTIMATE.index("toMarking_M")


def chen(predictor, lookout=False, **filters):
    """The Chen driver with the filters of the spec `scripted@name=value,...`."""
    return ChenDriver(predictor, lookout=lookout, filters=make_filters(DriverSpec("scripted", tuple(filters.items())),
                                                                      lookout))


def test_smoothing_mixes_every_indicator_with_the_previous_estimate():
    rows = [_row(40.0, 1.0), _row(20.0, 3.0)]
    e = _estimates(chen(Scripted(rows), smoothing=0.25), 2)
    assert e[1][MM] == pytest.approx(0.25 * 40 + 0.75 * 20)
    assert e[1][M] == pytest.approx(0.25 * 1 + 0.75 * 3)


def test_the_gap_hold_takes_a_closer_car_at_once_and_a_farther_one_slowly():
    rows = [_row(40.0, 1.0), _row(10.0, 3.0), _row(50.0, 2.0), _row(50.0, 2.0)]
    e = _estimates(chen(Scripted(rows), gap_hold=0.5), 4)
    assert e[1][MM] == pytest.approx(10.0)                  # closer: at once, not 0.5 * 40 + 0.5 * 10
    assert e[2][MM] == pytest.approx(0.5 * 10 + 0.5 * 50)   # farther: halfway
    assert e[3][MM] == pytest.approx(0.5 * 30 + 0.5 * 50)
    assert e[1][M] == pytest.approx(3.0)                    # the lateral indicators are not touched


def test_no_filter_passes_the_estimates_through():
    rows = [_row(40.0), _row(10.0), _row(50.0)]
    e = _estimates(ChenDriver(Scripted(rows)), 3)
    assert [x[MM] for x in e] == [40.0, 10.0, 50.0]


def test_the_pass_memory_carries_only_the_neighbour_gaps_of_a_car_being_passed():
    """docs/controller.md: dist_RR closing at 2 m/s and then lost is carried on; dist_LL and dist_MM, whose cars
    were not being passed, are not."""
    rr, ll = ESTIMATE.index("dist_RR"), ESTIMATE.index("dist_LL")

    def row(k):
        r = _row(50.0 if k < 20 else 8.0 + 0.2 * k)          # dist_MM: far, then near and opening: not carried
        r[INDICATORS.index("dist_RR")] = 14.0 - 0.2 * k if k < 20 else 60.0
        r[INDICATORS.index("dist_LL")] = 12.0 if k < 20 else 60.0     # steady: not being passed
        return r
    e = _estimates(chen(Scripted([row(k) for k in range(40)]), pass_memory=10.0), 40)
    assert e[20][rr] == pytest.approx(14.0 - 0.2 * 20, abs=0.05)    # lost, carried on at 2 m/s
    assert e[20][ll] == 60.0 and e[25][MM] == pytest.approx(8.0 + 0.2 * 25)
    without = _estimates(ChenDriver(Scripted([row(k) for k in range(40)])), 40)
    assert without[20][rr] == 60.0


class ScriptedRear(Scripted):
    """A predictor of the rear labels only (as the extended set's rear network), scripted."""
    outputs = ("dist_LB", "dist_RB", "closing_LB", "closing_RB")


def test_the_rear_memory_holds_a_car_lost_from_the_mirror_alongside_on_its_side_only():
    """docs/controller.md: dist_LB read closing in at 5 m/s and then far is held at 0 with its closing speed for
    15 m / 5 m/s = 3 s; the right side, whose car keeps its distance, passes through."""
    lb, rb, clb = ESTIMATE.index("dist_LB"), ESTIMATE.index("dist_RB"), ESTIMATE.index("closing_LB")
    rows = [(18.0 - 0.5 * k, 12.0, 5.0, 0.0) for k in range(5)] + [(100.0, 12.0, 0.0, 0.0)] * 40
    e = _estimates(chen(ScriptedRear(rows), lookout=True, rear_memory=10.0), 45)
    assert [x[lb] for x in e[5:35]] == [0.0] * 30 and [x[clb] for x in e[5:35]] == [5.0] * 30
    assert e[35][lb] == 100.0 and e[35][clb] == 0.0
    assert all(x[rb] == 12.0 for x in e)
    without = _estimates(ChenDriver(ScriptedRear(rows), lookout=True), 45)
    assert without[5][lb] == 100.0


def test_the_rear_memory_forgets_once_the_host_is_on_the_marking():
    from controller.highway.chen import LEFT_1, LEFT_2
    lb = ESTIMATE.index("dist_LB")
    rows = [(16.0, 100.0, 5.0, 0.0)] * 5 + [(100.0, 100.0, 0.0, 0.0)] * 10
    driver = chen(ScriptedRear(rows), lookout=True, rear_memory=10.0)
    driver.controller = SimpleNamespace(state=LEFT_1)      # phase 1: still in its lane, L2 reads the memory
    assert _estimates(driver, 6)[-1][lb] == 0.0
    driver.controller = SimpleNamespace(state=LEFT_2)      # on the marking: dist_LB changes meaning
    assert _estimates(driver, 1)[-1][lb] == 100.0


def test_with_the_rear_memory_the_pass_memory_hands_a_passed_car_over_to_the_mirror():
    """A car passed on the right at 2 m/s is lost at 10.2 m; the reckoning has it 10 m behind 10.1 s on. With the
    rear memory the lane stays taken until the rear view reads a car near behind on the right (`dist_RB` < 25 m)."""
    rr, rb = ESTIMATE.index("dist_RR"), ESTIMATE.index("dist_RB")

    class Both(Scripted):
        outputs = (*INDICATORS[:13], "dist_LB", "dist_RB", "closing_LB", "closing_RB")

    def row(k):
        r = _row(50.0)
        r[INDICATORS.index("dist_RR")] = 16.0 - 0.2 * k if k < 30 else 60.0
        return r + [100.0, 100.0 if k < 150 else 12.0, 0.0, 0.0]   # the mirror has it from frame 150 on
    rows = [row(k) for k in range(160)]
    with_mirror = _estimates(chen(Both(rows), lookout=True, pass_memory=30.0, rear_memory=10.0), 160)
    assert [e[rr] for e in with_mirror[135:150]] == [0.0] * 15 and with_mirror[150][rr] == 60.0
    assert with_mirror[151][rb] == 12.0
    alone = _estimates(chen(Both(rows), lookout=True, pass_memory=30.0), 160)
    assert [e[rr] for e in alone[135:150]] == [60.0] * 15
