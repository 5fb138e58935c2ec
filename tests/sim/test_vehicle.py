"""The host car's model: signs, limits and collisions."""
import math

import numpy as np
import pytest

from core.worlds.highway import STEER_LOCK_RAD, Action
from sim.collision import overlaps
from sim.highway.vehicle import VehicleParams, VehicleState, step_vehicle
from sim.track import load_track


@pytest.fixture(scope="module")
def track():
    return load_track("speedway", lanes=3)  # 1200 m of straight from s = 0


def run(track, state, action, seconds):
    for _ in range(int(round(seconds / 0.1))):
        state = step_vehicle(state, action, 0.1, track)
    return state


def test_positive_steer_turns_left(track):
    s = run(track, VehicleState(s=10, speed=15.0), Action(steer=0.2, accel=0.3), 1.0)
    assert s.heading > 0.05 and s.d > 0.1
    s = run(track, VehicleState(s=10, speed=15.0), Action(steer=-0.2, accel=0.3), 1.0)
    assert s.heading < -0.05 and s.d < -0.1


def test_full_lock_is_0_541052_rad_reached_at_the_steering_rate(track):
    s = step_vehicle(VehicleState(s=10, speed=5.0), Action(steer=1.0), 0.1, track)
    assert s.wheel_angle == pytest.approx(VehicleParams().steer_rate * 0.1)
    s = run(track, VehicleState(s=10, speed=5.0), Action(steer=1.0), 1.0)
    assert s.wheel_angle == pytest.approx(STEER_LOCK_RAD)
    s = run(track, VehicleState(s=10, speed=5.0), Action(steer=3.0), 1.0)  # commands are clipped
    assert s.wheel_angle == pytest.approx(STEER_LOCK_RAD)


def test_accel_speeds_up_brake_stops_never_reverses(track):
    s = run(track, VehicleState(s=10, speed=0.0), Action(accel=1.0), 3.0)
    assert 9.0 < s.speed < 14.0
    s = run(track, s, Action(brake=1.0), 3.0)
    assert s.speed == 0.0
    s = run(track, VehicleState(s=10, speed=20.0), Action(), 5.0)
    assert 15.0 < s.speed < 20.0  # coasting: drag and rolling resistance only


def test_braking_is_about_1_1_g(track):
    s = run(track, VehicleState(s=10, speed=20.0), Action(brake=1.0), 1.0)
    assert 20.0 - s.speed == pytest.approx(11.0, abs=1.0)


def test_grip_limits_the_turn_at_speed(track):
    # full lock at 25 m/s would need far more than 9 m/s^2 of lateral grip: the car runs wide instead
    s = run(track, VehicleState(s=10, speed=25.0), Action(steer=1.0, accel=0.2), 0.5)
    yaw_rate_cap = VehicleParams().max_lateral_accel / 25.0
    assert s.heading < yaw_rate_cap * 0.5 + 0.01


def test_the_car_follows_a_curve_in_track_coordinates():
    tr = load_track("ring", lanes=1)  # R = 200 m left turn everywhere
    delta = math.atan(2.7 / 200.0)    # kinematic steady state: tan(delta) = wheelbase / R (cos(beta) ~ 1)
    beta = math.atan(1.35 * math.tan(delta) / 2.7)  # the centre of gravity moves beta left of the body
    start = VehicleState(s=0.0, speed=15.0, heading=-beta, wheel_angle=delta)
    s = run(tr, start, Action(steer=delta / STEER_LOCK_RAD, accel=0.1), 10.0)
    assert s.s == pytest.approx(10.0 * 15.0, rel=0.1)
    assert abs(s.d) < 0.05 and abs(s.heading + beta) < 0.002


def test_oriented_box_overlaps():
    a = (0.0, 0.0, 0.0, 4.6, 1.9)
    cars = np.array([[4.5, 0.0, 0.0, 4.6, 1.9],    # nose to tail, overlapping 0.1 m
                     [4.7, 0.0, 0.0, 4.6, 1.9],    # 0.1 m apart
                     [0.0, 1.8, 0.0, 4.6, 1.9],    # side by side, touching
                     [0.0, 2.0, 0.0, 4.6, 1.9],    # side by side, apart
                     [3.0, 2.0, 0.6, 4.6, 1.9],    # turned towards us, a corner inside
                     [30.0, 0.0, 0.0, 4.6, 1.9]])
    assert overlaps(a, cars).tolist() == [True, False, True, False, True, False]
    assert overlaps(a, np.zeros((0, 5))).tolist() == []
