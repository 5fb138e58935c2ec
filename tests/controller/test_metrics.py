"""Closed-loop metrics, rule by rule."""
import numpy as np
import pytest

from controller.highway.metrics import ClosedLoopMetrics


def feed(m, steps):
    for s in steps:
        m.update(**s)


def step(speed=20.0, lane=1, in_lane=True, collision=False, off_road=False, gaps=()):
    return dict(speed=speed, lane=lane, in_lane=in_lane, collision=collision, off_road=off_road, gaps=np.array(gaps))


def test_distance_time_laps_and_speed():
    m = ClosedLoopMetrics(track_length=100.0, dt=0.1)
    feed(m, [step(speed=20.0)] * 100)
    r = m.report()
    assert r["simulated_time_s"] == 10.0 and r["distance_m"] == pytest.approx(200.0)
    assert r["laps"] == pytest.approx(2.0) and r["mean_speed_mps"] == pytest.approx(20.0)


def test_collisions_and_off_road_count_events_not_steps():
    m = ClosedLoopMetrics(100.0, 0.1)
    flags = [False, True, True, True, False, True, False]
    feed(m, [step(collision=c, off_road=c) for c in flags])
    assert m.collisions == 2 and m.off_road_events == 2


def test_lane_changes_and_in_lane_share():
    m = ClosedLoopMetrics(100.0, 0.1)
    feed(m, [step(lane=k, in_lane=k != 2) for k in (1, 1, 0, 0, 1, 2)])
    assert m.lane_changes == 3
    assert m.report()["in_lane_share"] == pytest.approx(5 / 6, abs=1e-4)


def test_overtakes_and_being_overtaken():
    m = ClosedLoopMetrics(1000.0, 0.1)
    # car 0 is passed by the host (ahead -> behind); car 1 passes the host; car 2 wraps at the seam (not a pass)
    feed(m, [step(gaps=[3.0, -2.0, 480.0]), step(gaps=[0.5, -0.5, 495.0]), step(gaps=[-1.0, 1.0, -499.0])])
    assert m.overtakes == 1 and m.overtaken == 1


def test_stage_times_per_step():
    m = ClosedLoopMetrics(100.0, 0.1)
    feed(m, [step()] * 4)
    m.add_time("render", 0.02)
    m.wall_time = 0.04
    r = m.report()
    assert r["stage_ms_per_step"]["render"] == pytest.approx(5.0)
    assert r["loop_rate_hz"] == pytest.approx(100.0)
