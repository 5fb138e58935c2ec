"""The highway's closed-loop metrics (controller/highway/metrics.py), rule by rule."""
from types import SimpleNamespace

import numpy as np
import pytest

from controller.highway.metrics import HighwayMetrics


def feed(m, steps):
    for s in steps:
        m.update(**s)


def step(speed=20.0, lane=1, in_lane=True, collision=False, off_road=False, gaps=()):
    return dict(speed=speed, lane=lane, in_lane=in_lane, collision=collision, off_road=off_road, gaps=np.array(gaps))


def test_distance_time_laps_and_speed():
    m = HighwayMetrics(track_length=100.0, dt=0.1)
    feed(m, [step(speed=20.0)] * 100)
    r = m.report()
    assert r["simulated_time_s"] == 10.0 and r["distance_m"] == pytest.approx(200.0)
    assert r["laps"] == pytest.approx(2.0) and r["mean_speed_mps"] == pytest.approx(20.0)


def test_collisions_and_off_road_count_events_not_steps():
    m = HighwayMetrics(100.0, 0.1)
    flags = [False, True, True, True, False, True, False]
    feed(m, [step(collision=c, off_road=c) for c in flags])
    assert m.collisions == 2 and m.off_road_events == 2


def test_lane_changes_and_in_lane_share():
    m = HighwayMetrics(100.0, 0.1)
    feed(m, [step(lane=k, in_lane=k != 2) for k in (1, 1, 0, 0, 1, 2)])
    assert m.lane_changes == 3
    assert m.report()["in_lane_share"] == pytest.approx(5 / 6, abs=1e-4)


def test_overtakes_and_being_overtaken():
    m = HighwayMetrics(1000.0, 0.1)
    # car 0 is passed by the host (ahead -> behind); car 1 passes the host; car 2 wraps at the seam (not a pass)
    feed(m, [step(gaps=[3.0, -2.0, 480.0]), step(gaps=[0.5, -0.5, 495.0]), step(gaps=[-1.0, 1.0, -499.0])])
    assert m.overtakes == 1 and m.overtaken == 1


def test_stage_times_per_step():
    m = HighwayMetrics(100.0, 0.1)
    feed(m, [step()] * 4)
    m.add_time("render", 0.02)
    m.wall_time = 0.04
    r = m.report()
    assert r["stage_ms_per_step"]["render"] == pytest.approx(5.0)
    assert r["loop_rate_hz"] == pytest.approx(100.0)


def _obs(s_ego, s_cars, lane=1, speed=20.0):
    cars = np.array([[0.0, 0.0, 0.0, s] for s in s_cars])
    truth = SimpleNamespace(ego=np.array([0.0, 0.0, 0.0, s_ego, 0.0]), cars=cars, speed=speed, lanes_left=lane,
                            in_lane=True)
    return SimpleNamespace(truth=truth, collision=False, off_road=False)


def test_a_world_is_observed_through_its_tracks_gaps():
    """`of(world)` takes the track's length and gap function; `observe` feeds `update` from the truth: the host's
    and the cars' along-track positions become the gaps (here a 1000 m loop, wrapping at the seam)."""
    def gap(s_from, s_to):
        return (np.asarray(s_to) - s_from + 500.0) % 1000.0 - 500.0

    world = SimpleNamespace(track=SimpleNamespace(length=1000.0, gap=gap), dt=0.1)
    m = HighwayMetrics.of(world)
    plain = HighwayMetrics(1000.0, 0.1)
    for s_ego, s_cars in [(0.0, [3.0, 998.0]), (2.5, [3.0, 1.5]), (5.0, [3.5, 6.0])]:
        m.observe(_obs(s_ego, s_cars))
        plain.update(20.0, 1, True, False, False, gap(s_ego, np.array(s_cars)))
    assert m.overtakes == 1 and m.overtaken == 1 and m.report() == plain.report()
    with pytest.raises(ValueError, match="gap"):
        HighwayMetrics(1000.0, 0.1).observe(_obs(0.0, [3.0]))
    HighwayMetrics(1000.0, 0.1).observe(_obs(0.0, []))   # no cars: no gaps needed
