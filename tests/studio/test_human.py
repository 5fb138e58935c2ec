"""The person at the controls (docs/studio.md): the keyboard's ramps, the gamepad's axes, the take-over's hold and
each world's command, one test per rule."""
from __future__ import annotations

import math

import numpy as np
import pytest

from core.worlds import highway as hw
from core.worlds import sidewalk as sw
from drivestudio.studio.human import (
    GAMEPAD_DEADZONE,
    KEY_CENTRE_RATE,
    KEY_PEDAL_RATE,
    KEY_PEDAL_RELEASE,
    KEY_STEER_RATE,
    TAKEOVER_HOLD,
    HumanDriver,
    HumanInput,
    Keys,
    Pad,
)
from drivestudio.worlds import get
from drivestudio.worlds.sidewalk.studio import FORWARD as SIDEWALK_FORWARD
from drivestudio.worlds.sidewalk.studio import REVERSE as SIDEWALK_REVERSE
from sim.highway.vehicle import VehicleParams

MAPS = {name: get(name).studio().human for name in ("highway", "sidewalk")}   # each world's, through its plugin

DT = 1 / 30


def steps(h: HumanInput, n: int, dt: float = DT):
    out = None
    for _ in range(n):
        out = h.advance(dt)
    return out


def test_a_held_arrow_ramps_the_steering_toward_full_lock_at_its_rate():
    h = HumanInput()
    h.set(Keys(right=True), None)
    assert h.advance(DT)[0] == pytest.approx(KEY_STEER_RATE * DT)     # + right
    assert steps(h, 5)[0] == pytest.approx(6 * KEY_STEER_RATE * DT)
    assert steps(h, 100)[0] == 1.0                                      # and no further
    h2 = HumanInput()
    h2.set(Keys(left=True), None)
    assert h2.advance(DT)[0] == pytest.approx(-KEY_STEER_RATE * DT)    # left is negative


def test_released_steering_returns_to_the_centre_at_the_centring_rate():
    h = HumanInput()
    h.set(Keys(right=True), None)
    steps(h, 100)
    h.set(Keys(), None)
    assert h.advance(DT)[0] == pytest.approx(1 - KEY_CENTRE_RATE * DT)
    assert steps(h, 100)[0] == 0.0


def test_countersteering_goes_back_through_the_centre_fast_then_ramps_out():
    h = HumanInput()
    h.set(Keys(right=True), None)
    steps(h, 100)
    h.set(Keys(left=True), None)
    assert h.advance(DT)[0] == pytest.approx(1 - KEY_CENTRE_RATE * DT)    # toward the centre: the fast rate
    to_centre = round(1 / (KEY_CENTRE_RATE * DT))      # 6 steps of 1/30 s at 5/s
    steps(h, to_centre - 1)
    assert h.steer == 0.0
    assert h.advance(DT)[0] == pytest.approx(-KEY_STEER_RATE * DT)        # outward: the ramp again
    h3 = HumanInput()                                   # a step that crosses the centre ramps out for its rest
    h3.steer = 0.1
    h3.set(Keys(left=True), None)
    rest = DT - 0.1 / KEY_CENTRE_RATE
    assert h3.advance(DT)[0] == pytest.approx(-KEY_STEER_RATE * rest)


def test_pedals_rise_while_held_and_fall_when_released():
    h = HumanInput()
    h.set(Keys(up=True), None)
    _, throttle, brake = steps(h, 3)
    assert throttle == pytest.approx(3 * KEY_PEDAL_RATE * DT) and brake == 0.0
    steps(h, 100)
    h.set(Keys(down=True), None)
    _, throttle, brake = h.advance(DT)
    assert throttle == pytest.approx(1 - KEY_PEDAL_RELEASE * DT)
    assert brake == pytest.approx(KEY_PEDAL_RATE * DT)


def test_a_gamepad_is_used_as_it_is_beyond_its_deadzone_and_overrides_the_keys():
    h = HumanInput()
    h.set(Keys(left=True), Pad(steer=0.4, throttle=0.7, brake=0.0))
    assert h.advance(DT) == (0.4, 0.7, 0.0)                              # no ramp, and the key is ignored
    h.set(Keys(), Pad(steer=GAMEPAD_DEADZONE / 2, throttle=0.5))
    assert h.advance(DT) == (0.0, 0.5, 0.0)                              # a resting stick is centred
    h.set(Keys(), Pad(steer=GAMEPAD_DEADZONE / 2))
    assert not Pad(steer=GAMEPAD_DEADZONE / 2).active


def test_a_take_over_lasts_while_touched_and_for_the_hold_after_letting_go():
    h = HumanInput()
    h.advance(DT)
    assert not h.touching
    h.set(Keys(up=True), None)
    h.advance(DT)
    assert h.touching
    h.set(Keys(), None)
    held = int(round(TAKEOVER_HOLD / DT))
    steps(h, held - 1)
    assert h.touching
    h.advance(DT)
    assert not h.touching
    h.set(Keys(), Pad(throttle=0.5))     # a gamepad's axis is a touch too
    h.advance(DT)
    assert h.touching
    h.release()                          # the page went away: nothing is held
    steps(h, held)
    assert not h.touching and h.throttle == 0.0


def test_highway_command_steers_left_positive_with_pedals_as_they_are():
    m = MAPS["highway"]
    a = m.action(1.0, 0.3, 0.2, speed=1.0)    # full right, slowly: full lock
    assert a.tolist() == pytest.approx([-1.0, 0.3, 0.2])
    assert m.action(-1.0, 0.0, 0.0, 1.0)[0] == pytest.approx(1.0)


def test_full_steering_turns_a_fast_car_at_the_declared_lateral_acceleration():
    for name, lock, wheelbase in (("highway", hw.STEER_LOCK_RAD, VehicleParams().wheelbase),
                                  ("sidewalk", sw.STEER_LOCK_RAD, sw.WHEELBASE)):
        m = MAPS[name]
        v = 20.0 if name == "highway" else 4.0
        fraction = m.steer_limit(v)
        assert fraction < 1.0
        accel = v * v * math.tan(fraction * lock) / wheelbase
        assert accel == pytest.approx(m.lateral_accel, rel=1e-9)
        assert m.steer_limit(0.5) == 1.0       # slow: full lock


def test_sidewalk_command_is_centred_at_half_and_full_throttle_asks_the_forward_speed():
    m = MAPS["sidewalk"]
    assert m.action(0.0, 0.0, 0.0, 0.0).tolist() == [0.5, 0.5]
    steer, motor = m.action(1.0, 1.0, 0.0, 0.0)
    assert steer == 1.0                                                  # full right is 1
    assert (2 * motor - 1) * sw.TOP_SPEED == pytest.approx(SIDEWALK_FORWARD * sw.TOP_SPEED) == pytest.approx(4.5)
    _, motor = m.action(0.0, 0.0, 1.0, 0.0)
    assert (2 * motor - 1) * sw.TOP_SPEED == pytest.approx(-SIDEWALK_REVERSE * sw.TOP_SPEED) == pytest.approx(-3.0)


def test_the_human_driver_reads_the_speed_from_the_record_and_has_no_estimate():
    h = HumanInput()
    h.set(Keys(right=True), None)
    drv = HumanDriver(MAPS["highway"], 0.1, 15, hw.HIGHWAY.index("speed"), h)
    record = np.zeros(len(hw.HIGHWAY.truth))
    record[hw.HIGHWAY.index("speed")] = 25.0

    class P:
        frames = (None,)
        t = 0.0
    P.record = record
    for _ in range(25):            # at 25 m/s a held key takes 2 s to full steering
        action, est = drv.act(P)
    assert action[0] == pytest.approx(-MAPS["highway"].steer_limit(25.0))
    assert np.isnan(est).all() and est.shape == (15,)


def test_the_steering_limit_and_the_keys_ramp_fall_with_speed_as_the_geometry_gives():
    """Full steering turns the car at lateral_accel (full lock when slow); a held key builds that turn at most at
    lateral_jerk, so that fast, full steering takes lateral_accel / lateral_jerk seconds at any speed; slow, the
    key's own rate."""
    for name, lock, wheelbase in (("highway", hw.STEER_LOCK_RAD, VehicleParams().wheelbase),
                                  ("sidewalk", sw.STEER_LOCK_RAD, sw.WHEELBASE)):
        m = MAPS[name]
        speeds = np.linspace(0.0, 40.0 if name == "highway" else 9.0, 200)
        limits = [m.steer_limit(v) for v in speeds]
        rates = [m.steer_rate(v, KEY_STEER_RATE) for v in speeds]
        assert limits[0] == 1.0 and rates[0] == KEY_STEER_RATE            # standing: full lock at the key's rate
        assert all(b <= a + 1e-12 for a, b in zip(limits, limits[1:]))    # both only fall with speed
        assert all(b <= a + 1e-12 for a, b in zip(rates, rates[1:]))
        for v, limit, rate in zip(speeds, limits, rates):
            turn = v * v * math.tan(limit * lock) / wheelbase            # full steering's lateral acceleration
            assert turn == pytest.approx(m.full_lateral_accel(v), abs=1e-9)
            assert turn <= m.lateral_accel + 1e-9
            assert rate * turn <= max(m.lateral_jerk, KEY_STEER_RATE * turn) + 1e-9
            if limit < 1.0:                                               # fast: the turn is the declared one
                assert turn == pytest.approx(m.lateral_accel)
                assert rate == pytest.approx(min(KEY_STEER_RATE, m.lateral_jerk / m.lateral_accel))
    highway = MAPS["highway"]
    assert highway.steer_rate(20.0, KEY_STEER_RATE) == pytest.approx(0.5)     # 2 s to full steering at speed
    assert highway.steer_limit(20.0) == pytest.approx(0.075, abs=0.001)


def test_a_held_arrow_ramps_at_the_rate_it_is_given():
    h = HumanInput()
    h.set(Keys(left=True), None)
    assert h.advance(0.1, steer_rate=0.5)[0] == pytest.approx(-0.05)
    h.set(Keys(), None)
    assert h.advance(0.1, steer_rate=0.5)[0] == 0.0                    # centring at its own rate, fast
