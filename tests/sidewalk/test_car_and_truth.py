"""The car obeys MultiNet's command conventions, and the truth record is exact geometry."""
import math

import numpy as np
import pytest

from core.worlds.sidewalk import CAR_LENGTH, CAR_WIDTH, SIDEWALK
from sim.sidewalk.car import CarState
from sim.sidewalk.layout import OBSTACLE_SIZES
from sim.sidewalk.truth import GAP_CAP
from tests.sidewalk.helpers import STRAIGHT, world

IX = {n: SIDEWALK.index(n) for n in SIDEWALK.truth_names}


def drive(w, steer, motor, seconds):
    for _ in range(int(round(seconds / w.dt))):
        obs = w.step(np.array([steer, motor]))
    return obs.truth


def test_steer_and_motor_follow_multinets_conventions():
    w = world(start_s=2.0)
    assert drive(w, 0.5, 0.5, 1.0)["speed"] == 0.0                        # motor 0.5: stop
    t = drive(w, 0.5, 1.0, 3.0)
    assert t["speed"] == pytest.approx(9.0, abs=0.05)                    # motor 1: full speed, about 9 m/s
    w = world(start_s=2.0)
    drive(w, 0.5, 0.6, 2.0)
    yaw0 = w.observe().truth["yaw"]
    assert drive(w, 1.0, 0.6, 0.5)["yaw"] < yaw0 - 0.3                     # steer 1: full right (clockwise)
    w = world(start_s=2.0)
    drive(w, 0.5, 0.6, 2.0)
    assert drive(w, 0.0, 0.6, 0.5)["yaw"] > yaw0 + 0.3                     # steer 0: full left
    w = world(start_s=30.0)
    t = drive(w, 0.5, 0.0, 3.0)
    assert -3.0 - 1e-9 <= t["speed"] < -2.5 and t["s"] < 30.0             # motor 0: full reverse (capped)
    t = w.step(np.array([np.nan, np.nan])).truth                          # no command: neutral
    assert (t["steer"], t["motor"]) == (0.5, 0.5)


def test_the_record_holds_the_command_the_car_is_under():
    w = world()
    obs = w.step(np.array([0.3, 0.7]))
    assert obs.record[IX["steer"]] == pytest.approx(0.3) and obs.record[IX["motor"]] == pytest.approx(0.7)
    assert obs.t == pytest.approx(1 / 30)


def test_obstacle_fields_are_exact():
    kind = "bench"
    length, width, _ = OBSTACLE_SIZES[kind]
    w = world(obstacles=[(kind, 20.0, -0.5, 0.0)], borders=((), ()))
    w.car = CarState(s=10.0, d=0.2)
    r = w.observe().record
    assert r[IX["obstacle_gap"]] == pytest.approx((20.0 - length / 2) - (10.0 + CAR_LENGTH / 2))
    assert r[IX["obstacle_d"]] == pytest.approx(-0.5) and r[IX["obstacle_width"]] == pytest.approx(width)
    assert not r[IX["obstacle_near"]]
    w.car = CarState(s=20.0 - length / 2 - CAR_LENGTH / 2 - 2.0, d=0.2)   # 2 m before it
    r = w.observe().record
    assert r[IX["obstacle_gap"]] == pytest.approx(2.0) and r[IX["obstacle_near"]] and not r[IX["collision"]]
    w.car = CarState(s=20.0, d=0.2)                                        # alongside, clear of it
    r = w.observe().record
    assert r[IX["obstacle_gap"]] < 0 and not r[IX["collision"]]
    w.car = CarState(s=20.0, d=-0.5 + width / 2 + CAR_WIDTH / 2 - 0.01)    # 1 cm into it
    assert w.observe().record[IX["collision"]]
    w.car = CarState(s=20.0 + length / 2 + CAR_LENGTH / 2 + 0.01, d=-0.5)  # just past it: the next one is none
    r = w.observe().record
    assert r[IX["obstacle_gap"]] == GAP_CAP and r[IX["obstacle_width"]] == 0.0


def test_border_clearance_and_contact_are_exact():
    face = 1.25
    w = world(borders=(((5.0, 40.0, face),), ((30.0, 50.0, -1.3),)))
    w.car = CarState(s=20.0, d=0.3)
    r = w.observe().record
    assert r[IX["border_left"]] == pytest.approx(face - 0.3 - CAR_WIDTH / 2)
    assert r[IX["border_right"]] == 5.0                                      # none beside the car on the right
    w.car = CarState(s=20.0, d=0.3, heading=0.2)                            # turned: the front corner reaches out
    reach = 0.3 + CAR_LENGTH / 2 * math.sin(0.2) + CAR_WIDTH / 2 * math.cos(0.2)
    assert w.observe().record[IX["border_left"]] == pytest.approx(face - reach, abs=1e-9)
    w.car = CarState(s=35.0, d=-0.2)
    assert w.observe().record[IX["border_right"]] == pytest.approx(1.3 - 0.2 - CAR_WIDTH / 2)
    w.car = CarState(s=20.0, d=face - CAR_WIDTH / 2 + 0.01)
    r = w.observe().record
    assert r[IX["border_left"]] < 0 and r[IX["collision"]] and r[IX["off_path"]]


def test_path_fields_are_exact():
    w = world(borders=((), ()))
    w.car = CarState(s=STRAIGHT + 5.0, d=-0.4, heading=0.1)          # in the first bend (radius 10, left)
    t = w.observe().truth
    assert t["curvature"] == pytest.approx(0.1) and t["curvature_ahead"] == pytest.approx(0.1)
    w.car = CarState(s=STRAIGHT - 0.5, d=0.0)                         # 0.5 m of straight, then 1 m of bend
    assert w.observe().truth["curvature_ahead"] == pytest.approx(0.1 * 1.0 / 1.5)
    x, y, tangent = w.path.track.pose(STRAIGHT + 5.0, -0.4)
    w.car = CarState(s=STRAIGHT + 5.0, d=-0.4, heading=0.1)
    t = w.observe().truth
    assert (t["x"], t["y"]) == pytest.approx((x, y)) and t["yaw"] == pytest.approx(tangent + 0.1)
    assert t["path_width"] == 2.0 and not t["off_path"]
    w.car = CarState(s=10.0, d=1.05)
    assert w.observe().truth["off_path"]
    w.car = CarState(s=10.0, d=2.1)
    assert w.observe().end == "off the path"
    w.recover()
    obs = w.observe()
    assert obs.end is None and obs.truth["d"] == 0.0 and obs.truth["speed"] == 0.0


def test_the_lead_car_comes_with_follow_mode():
    w = world(mode="direct")
    assert w.observe().truth["lead_gap"] == GAP_CAP
    w.set_mode("follow")
    t = w.observe().truth
    assert t["behaviour"] == 1 and t["lead_gap"] == pytest.approx(1.6, abs=0.01)
    lead = w.lead.state
    assert t["lead_gap"] == pytest.approx(w.path.track.gap(t["s"], lead.s) - CAR_LENGTH)
    w.set_mode("furtive")
    t = w.observe().truth
    assert t["behaviour"] == 2 and t["lead_gap"] == GAP_CAP and w.lead is None
    with pytest.raises(ValueError, match="unknown behavioural mode"):
        w.set_mode("sneaky")
