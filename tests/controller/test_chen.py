"""The Chen controller, one test per rule of docs/controller.md (numbered as there).

Expected numbers are worked out from the document by hand (0.541052, road width 8, the gains and the
thresholds written out), not read back from ChenParams, so a wrong constant or sign fails a test.
Hand-made indicator vectors: every indicator inactive (docs/affordances.md) except those given.
The closed-loop tests drive the real kinematic car on the exact indicators at 10 Hz.
"""
import math

import numpy as np
import pytest

from controller.highway import ChenController, ChenParams
from core.worlds.highway import INACTIVE, INDICATORS, STEER_LOCK_RAD, Action
from sim.highway.traffic import ScriptedTraffic
from sim.highway.truth import affordances
from sim.highway.vehicle import VehicleState
from sim.track import load_track
from tests.controller.drive_helpers import collided, drive

LOCK = 0.541052   # [rad] the doc's steering gain divisor
ROAD = 8.0        # [m] the doc's road_width


def ind(**given):
    """The 14 indicators in canonical order: angle 0, fast 0, inactive values, then `given`."""
    values = {"angle": 0.0, **INACTIVE, "fast": 0.0, **given}
    assert set(values) == set(INDICATORS), set(values) ^ set(INDICATORS)
    return [values[n] for n in INDICATORS]


def in_lane(offset=0.0, lanes=3, lane=1, **given):
    """A car `offset` [m] left of the centre of `lane` (0 = leftmost) on an `lanes`-lane road, empty road.

    Only the in-lane system is filled in; on-marking indicators stay inactive unless given."""
    w = 4.0
    markings = [(lanes / 2 - j) * w for j in range(lanes + 1)]
    d = (lanes / 2 - lane - 0.5) * w + offset
    v = {"toMarking_ML": d - markings[lane], "toMarking_MR": d - markings[lane + 1],
         "dist_MM": 60.0}
    if lane >= 1:
        v.update(toMarking_LL=d - markings[lane - 1], dist_LL=60.0)
    if lane + 2 <= lanes:
        v.update(toMarking_RR=d - markings[lane + 2], dist_RR=60.0)
    v.update(given)
    return ind(**v)


def steer_of(ctrl, vec, speed=15.0):
    return ctrl.act(vec, speed).steer


def feed(ctrl, vec, frames, speed=15.0):
    action = None
    for _ in range(frames):
        action = ctrl.act(vec, speed)
    return action


# --- the interface --------------------------------------------------------------------------------------


def test_params_hold_the_documented_constants():
    p = ChenParams()
    assert (p.road_width, p.steer_lock, p.timer_set, p.timer_set_two_lane_after_change) == (8.0, LOCK, 60, 30)
    assert (p.v_max, p.follow_c, p.follow_d) == (20.0, 2.772, -0.693)
    assert p.steer_lock == STEER_LOCK_RAD
    assert (p.coe_keep, p.coe_keep_near_marking, p.coe_on_marking, p.coe_change, p.coe_change_phase_2) == \
        (1.5, 0.4, 0.3, 6.0, 20.0)
    assert (p.follow_gap, p.occupied_gap, p.left_lane_exists, p.right_lane_exists) == (15.0, 20.0, -8.0, 8.0)
    assert (p.in_lane_span, p.steer_trend_bound, p.boost_above, p.boost_slope, p.boost_offset) == \
        (5.5, 0.2, 0.1, 2.5, 0.75)
    assert (p.v_cruise, p.trend_slowdown, p.v_min, p.accel_gain, p.brake_gain) == (20.0, 4.5, 10.0, 0.2, 0.1)


def test_act_returns_an_action_and_accepts_the_papers_13():
    ctrl = ChenController(3)
    a = ctrl.act(in_lane(fast=1.0), 15.0)
    assert isinstance(a, Action)
    ctrl.reset()
    b = ctrl.act(in_lane()[:13], 15.0)  # no `fast`: desired 20 - 4.5 * 0 = 20 all the same
    assert a == b
    with pytest.raises(ValueError):
        ctrl.act([0.0] * 12, 15.0)


def test_reset_forgets_everything():
    ctrl = ChenController(3)
    feed(ctrl, in_lane(), 61)
    ctrl.act(in_lane(dist_MM=10.0), 15.0)
    assert ctrl.state == "left-1" and ctrl.lane_changes_started == 1
    ctrl.reset()
    assert ctrl.state == "keep" and ctrl.lane_changes_started == 0
    assert not ctrl.left_clear and not ctrl.right_clear and ctrl.steer_trend == 0.0


# --- rule 2 (follow) and rule 7: speed ---------------------------------------------------------------------


def test_follow_speed_curve_0_10_15_at_5_10_15_m_and_never_negative():
    ctrl = ChenController(3)
    assert ctrl.follow_speed(5.0) == pytest.approx(0.0, abs=1e-3)
    assert ctrl.follow_speed(10.0) == pytest.approx(10.0, abs=1e-2)
    assert ctrl.follow_speed(15.0) == pytest.approx(15.0, abs=1e-2)
    assert ctrl.follow_speed(2.0) == 0.0


def test_follow_speed_limits_desired_speed_when_both_neighbours_blocked():
    ctrl = ChenController(3)  # cold: no neighbour lane has proved clear yet, so it follows
    a = ctrl.act(in_lane(dist_MM=10.0, fast=1.0), 12.0)
    assert ctrl.state == "keep"
    assert (a.accel, a.brake) == (0.0, pytest.approx(0.1 * (12.0 - 10.0), abs=1e-3))
    a = ctrl.act(in_lane(dist_MM=15.0 - 1e-9, fast=1.0), 14.0)
    assert (a.accel, a.brake) == (pytest.approx(0.2 * (15.0 - 14.0 + 1), abs=1e-3), 0.0)
    a = ctrl.act(in_lane(dist_MM=4.0, fast=1.0), 3.0)  # slow_down 0 m/s: brake, whatever `fast` says
    assert (a.accel, a.brake) == (0.0, pytest.approx(0.3))


def test_desired_speed_is_20_when_fast():
    ctrl = ChenController(3)
    turning = in_lane(angle=-0.3, fast=1.0)  # steers hard right: a big trend that `fast` overrides
    feed(ctrl, turning, 5)
    assert abs(ctrl.steer_trend) > 1.0
    a = ctrl.act(turning, 19.0)
    assert (a.accel, a.brake) == (pytest.approx(0.2 * (20 - 19 + 1)), 0.0)
    a = ctrl.act(turning, 21.0)
    assert (a.accel, a.brake) == (0.0, pytest.approx(0.1 * (21 - 20)))


def test_desired_speed_falls_by_4_5_per_unit_of_steer_trend():
    ctrl = ChenController(3)
    angle = -0.1 * LOCK * 1.5  # centred, so steer = angle / 0.541052 / 1.5 = -0.1 (right: no boost)
    vec = in_lane(angle=angle)
    feed(ctrl, vec, 4)
    a = ctrl.act(vec, 15.0)  # the trend now sums five commands of -0.1, this frame's included
    assert a.steer == pytest.approx(-0.1)
    assert ctrl.steer_trend == pytest.approx(-0.5)
    desired = 20 - 4.5 * 0.5
    assert (a.accel, a.brake) == (pytest.approx(0.2 * (desired - 15 + 1)), 0.0)
    a = ctrl.act(vec, 19.0)
    assert (a.accel, a.brake) == (0.0, pytest.approx(0.1 * (19 - desired)))


def test_desired_speed_is_floored_at_10():
    ctrl = ChenController(3)
    vec = in_lane(angle=-0.5 * LOCK * 1.5)  # steer -0.5 a frame: trend -2.5, 20 - 11.25 < 10
    feed(ctrl, vec, 5)
    a = ctrl.act(vec, 12.0)
    assert (a.accel, a.brake) == (0.0, pytest.approx(0.1 * (12 - 10)))
    a = ctrl.act(vec, 9.5)
    assert (a.accel, a.brake) == (pytest.approx(0.2 * (10 - 9.5 + 1)), 0.0)


def test_accel_and_brake_saturate_at_1():
    ctrl = ChenController(3)
    a = ctrl.act(in_lane(fast=1.0), 0.0)
    assert (a.accel, a.brake) == (1.0, 0.0)
    a = ctrl.act(in_lane(fast=1.0), 35.0)
    assert (a.accel, a.brake) == (0.0, 1.0)


# --- rule 4 and rule 6: lane keeping and steering ----------------------------------------------------------


@pytest.mark.parametrize("angle", [0.05, -0.05])
def test_angle_sign_positive_points_right_so_steer_left(angle):
    # angle > 0: the car points to the right of the road; a positive (left) steer corrects it
    s = steer_of(ChenController(3), in_lane(angle=angle))
    assert s == pytest.approx(angle / LOCK / 1.5)
    assert np.sign(s) == np.sign(angle)


def test_car_left_of_centre_steers_right():
    s = steer_of(ChenController(3), in_lane(offset=0.5))  # center_line = (ML + MR) / 2 = +0.5
    assert s == pytest.approx(-0.5 / ROAD / LOCK / 1.5)
    assert s < 0


def test_car_right_of_centre_steers_left():
    s = steer_of(ChenController(3), in_lane(offset=-0.5))
    assert s == pytest.approx(0.5 / ROAD / LOCK / 1.5)
    assert s > 0


def test_in_lane_estimate_trusted_only_below_5_5():
    # same on-marking estimate in both: the lane right of the marking, centre 0.1 m to the right of the car
    on_marking = dict(toMarking_L=-5.9, toMarking_M=-1.9, toMarking_R=2.1)
    trusted = in_lane(toMarking_ML=-2.5, toMarking_MR=2.9, **on_marking)  # span 5.4: centre 0.2 m left
    s = steer_of(ChenController(3), trusted)
    assert s == pytest.approx(-0.2 / ROAD / LOCK / 0.4)  # toMarking_M < 1 too: coe 0.4
    untrusted = in_lane(toMarking_ML=-2.6, toMarking_MR=3.0, **on_marking)  # span 5.6: on-marking, coe 0.3
    s = steer_of(ChenController(3), untrusted)
    assert s == pytest.approx(-((2.1 - 1.9) / 2) / ROAD / LOCK / 0.3)


@pytest.mark.parametrize("last_ml, last_mr, lane_side", [(-3.4, 0.6, "left"), (-0.6, 3.4, "right")])
def test_on_marking_estimate_picks_the_side_the_car_came_from(last_ml, last_mr, lane_side):
    ctrl = ChenController(3)
    ctrl.act(in_lane(toMarking_ML=last_ml, toMarking_MR=last_mr), 15.0)
    # now on an internal marking, in-lane system inactive
    s = steer_of(ctrl, ind(toMarking_L=-4.3, toMarking_M=-0.3, toMarking_R=3.7))
    centre = (-4.3 - 0.3) / 2 if lane_side == "left" else (3.7 - 0.3) / 2
    assert s == pytest.approx(float(np.clip(-centre / ROAD / LOCK / 0.3, -1, 1)))
    assert (s > 0) == (lane_side == "left")


def test_on_marking_estimate_never_aims_past_a_road_edge():
    # a fresh controller (no in-lane estimate seen: the lane right of the marking would be taken) on the
    # right edge, where toMarking_R reads its inactive 7: the lane is the one left of the edge
    ctrl = ChenController(3)
    assert steer_of(ctrl, ind(toMarking_L=-5.0, toMarking_M=-1.0, toMarking_R=7.0)) == 1.0
    # last seen near its right marking, now 1 m outside the left edge (toMarking_L reads -7): steer back right
    ctrl = ChenController(3)
    ctrl.act(in_lane(lane=0, toMarking_ML=-3.4, toMarking_MR=0.6), 15.0)
    assert steer_of(ctrl, ind(toMarking_L=-7.0, toMarking_M=1.0, toMarking_R=5.0)) == -1.0


@pytest.mark.parametrize("outside", [1.6, 2.0, 2.4])
def test_far_outside_an_edge_of_wide_lanes_it_steers_back_onto_the_road(outside):
    """5 m lanes: beyond the right edge by more than 1.5 m, toMarking_L (d - m_{N-1}) is below -6.5 as well as the
    inactive toMarking_R = 7; the road lies to the left, so the controller steers left (and mirrored)."""
    w = 5.0
    ctrl = ChenController(3)
    right_edge = ind(toMarking_L=-w - outside, toMarking_M=-outside, toMarking_R=7.0)
    assert steer_of(ctrl, right_edge) > 0.5
    ctrl = ChenController(3)
    left_edge = ind(toMarking_L=-7.0, toMarking_M=outside, toMarking_R=w + outside)
    assert steer_of(ctrl, left_edge) < -0.5


def test_coe_0_4_when_toMarking_M_below_1():
    near = steer_of(ChenController(3), in_lane(angle=0.05, toMarking_M=0.9, toMarking_L=-3.1, toMarking_R=4.9))
    assert near == pytest.approx(0.05 / LOCK / 0.4)  # no boost: coe 0.4 is not > 1
    far = steer_of(ChenController(3), in_lane(angle=0.05, toMarking_M=1.0, toMarking_L=-3.0, toMarking_R=5.0))
    assert far == pytest.approx(0.05 / LOCK / 1.5)


def test_left_steer_above_0_1_is_boosted_when_keeping_lane():
    raw = 1.0 / ROAD / LOCK / 1.5  # car 1 m right of centre: 0.154
    s = steer_of(ChenController(3), in_lane(offset=-1.0))
    assert s == pytest.approx(raw * (2.5 * raw + 0.75))
    assert steer_of(ChenController(3), in_lane(offset=1.0)) == pytest.approx(-raw)  # right: no boost
    small = 0.09
    assert steer_of(ChenController(3), in_lane(angle=small * LOCK * 1.5)) == pytest.approx(small)


def test_steer_is_clipped_to_plus_minus_1():
    assert steer_of(ChenController(3), in_lane(angle=0.5, offset=-1.4)) == 1.0  # 0.83, boosted to 2.3
    assert steer_of(ChenController(3), in_lane(angle=-1.0, offset=1.4)) == -1.0  # -1.45
    near = dict(toMarking_L=-3.1, toMarking_M=0.9, toMarking_R=4.9)  # coe 0.4: no boost
    assert steer_of(ChenController(3), in_lane(angle=0.3, **near)) == 1.0  # 1.39


# --- rule 1: lane occupancy -------------------------------------------------------------------------------


def test_left_lane_clear_only_after_timer_set_frames():
    ctrl = ChenController(3)
    feed(ctrl, in_lane(), 60)
    assert not ctrl.left_clear and not ctrl.right_clear
    ctrl.act(in_lane(), 15.0)  # frame 61: the timer exceeds timer_set
    assert ctrl.left_clear and ctrl.right_clear


def test_one_near_reading_does_not_block_a_lane_two_in_a_row_do():
    ctrl = ChenController(3)  # pre_dist_L starts at 60: a near first reading is one reading
    ctrl.act(in_lane(dist_LL=10.0), 15.0)
    feed(ctrl, in_lane(), 60)
    assert ctrl.left_clear
    ctrl = ChenController(3)
    feed(ctrl, in_lane(), 61)
    ctrl.act(in_lane(dist_LL=10.0), 15.0)  # pre_dist_L was 60: one reading is not enough
    assert ctrl.left_clear
    ctrl.act(in_lane(dist_LL=10.0), 15.0)  # pre_dist_L < 20 and dist_LL < 20
    assert not ctrl.left_clear and ctrl.right_clear
    feed(ctrl, in_lane(), 60)
    assert not ctrl.left_clear
    ctrl.act(in_lane(), 15.0)
    assert ctrl.left_clear


def test_right_lane_occupancy_mirrors_left():
    ctrl = ChenController(3)
    feed(ctrl, in_lane(dist_RR=19.0), 100)
    assert ctrl.left_clear and not ctrl.right_clear
    feed(ctrl, in_lane(dist_RR=20.0), 61)  # 20 m is not "under 20"
    assert ctrl.right_clear


def test_overtake_waits_timer_set_frames_for_the_left_lane():
    ctrl = ChenController(3)
    following = in_lane(dist_MM=10.0, dist_RR=10.0)  # right lane blocked throughout
    for _ in range(60):
        ctrl.act(following, 15.0)
        assert ctrl.state == "keep"
    ctrl.act(following, 15.0)
    assert ctrl.state == "left-1" and ctrl.lane_changes_started == 1


# --- rule 2: overtake or follow ---------------------------------------------------------------------------


def warm(lanes=3, **given):
    """A controller that has driven straight for 61 frames with the given neighbourhood: lanes proved clear."""
    ctrl = ChenController(lanes)
    feed(ctrl, in_lane(lanes=lanes, **given), 61)
    return ctrl


def test_overtake_left_when_left_clear_and_dist_MM_below_15():
    ctrl = warm()
    ctrl.act(in_lane(dist_MM=15.0), 15.0)
    assert ctrl.state == "keep"  # 15 m is not "below 15", and the centre lane is preferred
    a = ctrl.act(in_lane(dist_MM=14.9), 15.0)
    assert ctrl.state == "left-1" and ctrl.lane_changes_started == 1
    assert a.accel > 0 and a.brake == 0  # no slow-down while overtaking
    assert not ctrl.left_clear and not ctrl.right_clear  # both timers reset


def steer_history(ctrl, steer, lanes=3, frames=5):
    """Fill the last five commands with `steer` (centred car, angle chosen; no boost for |steer| <= 0.1)."""
    feed(ctrl, in_lane(lanes=lanes, angle=steer * LOCK * 1.5), frames)
    assert ctrl.steer_trend == pytest.approx(frames * steer)


@pytest.mark.parametrize("trend_each, expected", [
    (0.0, "left-1"), (0.039, "left-1"),      # 0 <= trend < 0.2: left
    (0.041, "keep"),                         # trend 0.205 >= 0.2, and > 0 so not right either: follow
    (-0.01, "right-1"), (-0.039, "right-1"),  # below 0: the mirror test, -0.2 < trend <= 0
    (-0.041, "keep"),                        # trend -0.205: neither
])
def test_overtake_needs_the_steer_trend_bound(trend_each, expected):
    ctrl = warm()
    steer_history(ctrl, trend_each)
    ctrl.act(in_lane(dist_MM=10.0), 15.0)
    assert ctrl.state == expected


def test_two_lane_overtake_has_no_0_2_bound():
    ctrl = warm(lanes=2, lane=1)
    steer_history(ctrl, 0.08, lanes=2, frames=5)  # trend 0.4
    ctrl.act(in_lane(lanes=2, lane=1, dist_MM=10.0), 15.0)
    assert ctrl.state == "left-1"


def test_overtake_right_when_left_blocked():
    ctrl = warm(dist_LL=12.0)
    assert not ctrl.left_clear and ctrl.right_clear
    ctrl.act(in_lane(dist_MM=10.0, dist_LL=12.0), 15.0)
    assert ctrl.state == "right-1"


def test_overtake_right_when_there_is_no_left_lane():
    ctrl = ChenController(3)
    following = in_lane(lane=0, dist_MM=10.0)  # leftmost lane: toMarking_LL inactive (-9.5), dist_LL 75
    feed(ctrl, following, 60)
    assert ctrl.state == "keep" and ctrl.left_clear is False
    ctrl.act(following, 15.0)
    assert ctrl.state == "right-1"


def test_follow_when_both_neighbours_blocked():
    ctrl = warm(dist_LL=12.0, dist_RR=12.0)
    a = ctrl.act(in_lane(dist_MM=10.0, dist_LL=12.0, dist_RR=12.0, fast=1.0), 14.0)
    assert ctrl.state == "keep" and ctrl.lane_changes_started == 0
    assert (a.accel, a.brake) == (0.0, pytest.approx(0.1 * (14 - 10), abs=1e-3))


def test_one_lane_road_never_changes_lane():
    ctrl = ChenController(1)
    feed(ctrl, in_lane(lanes=1, lane=0), 61)
    feed(ctrl, in_lane(lanes=1, lane=0, dist_MM=10.0), 30)
    assert ctrl.state == "keep" and ctrl.lane_changes_started == 0


# --- rule 3: lane preference ------------------------------------------------------------------------------


@pytest.mark.parametrize("lanes, lane, expected", [
    (3, 2, "left-1"),   # right lane (no lane to its right): move left, to the centre
    (3, 0, "right-1"),  # left lane: move right
    (3, 1, "keep"),     # centre lane: stay
    (4, 0, "right-1"), (4, 1, "keep"), (4, 2, "keep"), (4, 3, "left-1"),  # off the edge lanes
    (1, 0, "keep"),     # no lane on either side
    (2, 0, "right-1"),  # two lanes prefer the right lane
    (2, 1, "keep"),
])
def test_lane_preference(lanes, lane, expected):
    ctrl = ChenController(lanes)
    vec = in_lane(lanes=lanes, lane=lane)
    feed(ctrl, vec, 60)
    assert ctrl.state == "keep"  # not before the lane has proved clear
    ctrl.act(vec, 15.0)
    assert ctrl.state == expected


def test_lane_preference_waits_for_the_target_lane_to_be_clear():
    ctrl = ChenController(3)
    feed(ctrl, in_lane(lane=2, dist_LL=15.0), 100)
    assert ctrl.state == "keep"
    ctrl = ChenController(2)
    feed(ctrl, in_lane(lanes=2, lane=0, dist_RR=15.0), 100)
    assert ctrl.state == "keep"


def test_no_lane_preference_on_a_marking():
    # in-lane system inactive (LL = -9.5 and RR = 9.5 at once): no lane change starts
    ctrl = ChenController(3)
    feed(ctrl, ind(toMarking_L=-4.0, toMarking_M=0.0, toMarking_R=4.0, dist_L=60.0, dist_R=60.0), 100)
    assert ctrl.lane_changes_started == 0


def test_two_lane_timer_is_30_after_an_overtake_then_60_again():
    ctrl = warm(lanes=2, lane=1)
    ctrl.act(in_lane(lanes=2, lane=1, dist_MM=10.0), 15.0)
    assert ctrl.state == "left-1"
    ctrl.act(ind(toMarking_L=-4.0, toMarking_M=0.0, toMarking_R=4.0), 15.0)  # on the centre marking
    assert ctrl.state == "left-2"
    beside = in_lane(lanes=2, lane=0, dist_RR=10.0)  # in the left lane, the slow car ahead on the right
    feed(ctrl, beside, 5)
    assert ctrl.state == "keep"
    left_lane = in_lane(lanes=2, lane=0)
    feed(ctrl, left_lane, 30)
    assert ctrl.state == "keep"
    ctrl.act(left_lane, 15.0)  # 31 clear frames: back to the right lane (rule 3, two lanes)
    assert ctrl.state == "right-1" and ctrl.lane_changes_started == 2
    right_lane = in_lane(lanes=2, lane=1)
    feed(ctrl, right_lane, 60)
    assert not ctrl.left_clear  # back in the right lane, the usual 60 frames
    ctrl.act(right_lane, 15.0)
    assert ctrl.left_clear


# --- rule 5: the lane-change state machine ------------------------------------------------------------------


def test_left_change_phase_1_then_phase_2_then_keep():
    ctrl = warm()
    # phase 1: aim at the left lane's centre (LL + ML) / 2, coe 6, no boost
    s = steer_of(ctrl, in_lane(dist_MM=10.0))
    assert ctrl.state == "left-1"
    assert s == pytest.approx(((-6 - 2) / 2) * -1 / ROAD / LOCK / 6)  # car 4 m right of target: steer left
    # phase 1 near the left marking: averaged with the on-marking estimate (L + M) / 2
    vec = in_lane(offset=1.2, toMarking_L=-4.8, toMarking_M=-0.8, toMarking_R=3.2)
    s = steer_of(ctrl, vec)
    centre = ((-4.8 - 0.8) / 2 + (-4.8 - 0.8) / 2) / 2
    assert ctrl.state == "left-1" and s == pytest.approx(-centre / ROAD / LOCK / 6)
    vec = in_lane(offset=1.2, toMarking_L=-4.8, toMarking_M=-0.8, toMarking_R=3.2, toMarking_LL=-5.5)
    s = steer_of(ctrl, vec)  # LL+ML disagrees with L+M here: the average is used
    centre = ((-5.5 - 0.8) / 2 + (-4.8 - 0.8) / 2) / 2
    assert s == pytest.approx(-centre / ROAD / LOCK / 6)
    # the in-lane estimate gives out: phase 2, (L + M) / 2 with coe 20
    s = steer_of(ctrl, ind(toMarking_L=-4.2, toMarking_M=-0.2, toMarking_R=3.8))
    assert ctrl.state == "left-2" and s == pytest.approx(2.2 / ROAD / LOCK / 20)
    s = steer_of(ctrl, ind(toMarking_L=-3.2, toMarking_M=0.8, toMarking_R=4.8, toMarking_ML=-1.2,
                           toMarking_MR=2.8, toMarking_LL=-5.2))
    assert ctrl.state == "left-2" and s == pytest.approx(1.2 / ROAD / LOCK / 20)
    # on-marking test fails (the marking is behind): back to lane keeping in the same frame
    s = steer_of(ctrl, in_lane(offset=-0.5, lane=0))
    assert ctrl.state == "keep" and s == pytest.approx(0.5 / ROAD / LOCK / 1.5)
    assert ctrl.lane_changes_started == 1


def test_left_phase_2_ends_when_toMarking_L_not_above_minus_5():
    ctrl = warm()
    ctrl.act(in_lane(dist_MM=10.0), 15.0)
    ctrl.act(ind(toMarking_L=-4.2, toMarking_M=-0.2, toMarking_R=3.8), 15.0)
    assert ctrl.state == "left-2"
    ctrl.act(ind(toMarking_L=-5.0, toMarking_M=-1.0, toMarking_R=3.0), 15.0)
    assert ctrl.state == "keep"


def test_right_change_mirrors_left():
    ctrl = warm(dist_LL=12.0)
    s = steer_of(ctrl, in_lane(dist_MM=10.0, dist_LL=12.0))
    assert ctrl.state == "right-1"
    assert s == pytest.approx(-((6 + 2) / 2) / ROAD / LOCK / 6)  # target 4 m right: steer right
    # near the right marking (toMarking_R < 5, toMarking_M > -1.5): averaged with (R + M) / 2
    vec = in_lane(offset=-1.2, toMarking_L=-3.2, toMarking_M=0.8, toMarking_R=4.8, toMarking_RR=5.5)
    s = steer_of(ctrl, vec)
    centre = ((5.5 + 0.8) / 2 + (4.8 + 0.8) / 2) / 2
    assert ctrl.state == "right-1" and s == pytest.approx(-centre / ROAD / LOCK / 6)
    s = steer_of(ctrl, ind(toMarking_L=-3.8, toMarking_M=0.2, toMarking_R=4.2))
    assert ctrl.state == "right-2" and s == pytest.approx(-2.2 / ROAD / LOCK / 20)
    ctrl.act(ind(toMarking_L=-5.0, toMarking_M=1.0, toMarking_R=4.9), 15.0)
    assert ctrl.state == "right-2"
    ctrl.act(ind(toMarking_L=-5.0, toMarking_M=1.0, toMarking_R=5.0), 15.0)  # toMarking_R < 5 fails
    assert ctrl.state == "keep"


def test_right_phase_2_ends_when_toMarking_M_not_above_minus_1_5():
    ctrl = warm(dist_LL=12.0)
    ctrl.act(in_lane(dist_MM=10.0, dist_LL=12.0), 15.0)
    ctrl.act(ind(toMarking_L=-3.8, toMarking_M=0.2, toMarking_R=4.2), 15.0)
    ctrl.act(ind(toMarking_L=-5.4, toMarking_M=-1.4, toMarking_R=2.6), 15.0)
    assert ctrl.state == "right-2"
    ctrl.act(ind(toMarking_L=-5.5, toMarking_M=-1.5, toMarking_R=2.5), 15.0)
    assert ctrl.state == "keep"


def test_no_boost_while_changing_lane():
    ctrl = warm()
    s = steer_of(ctrl, in_lane(dist_MM=10.0, offset=-1.0))  # target 5 m left: raw 5/8/0.541/6 = 0.19
    assert ctrl.state == "left-1" and s == pytest.approx(5 / ROAD / LOCK / 6)


# --- closed loop: the signs on the real car -----------------------------------------------------------------

TRACKS = {}


def track(name, lanes):
    if (name, lanes) not in TRACKS:
        TRACKS[name, lanes] = load_track(name, lanes=lanes)
    return TRACKS[name, lanes]


# (lanes, start lane, lane it should end in): the preferred lane of rule 3
START_LANES = [(1, 0, 0), (2, 1, 1), (2, 0, 1), (3, 1, 1), (3, 2, 1)]


@pytest.mark.parametrize("lanes, lane, end_lane", START_LANES)
@pytest.mark.parametrize("offset, heading", [(1.0, 0.15), (1.0, -0.15), (-1.0, 0.15), (-1.0, -0.15)])
def test_converges_to_lane_centre_from_off_centre_and_off_angle(lanes, lane, end_lane, offset, heading):
    tr = track("oval", lanes)
    ctrl = ChenController(lanes)
    start = VehicleState(s=20.0, d=tr.lane_centres[lane] + offset, heading=heading, speed=15.0)
    trace = drive(tr, ctrl, start, seconds=15.0)
    d = np.asarray(trace.d)
    assert np.all(np.abs(d) < tr.half_width), "left the road"
    assert np.all(np.asarray(trace.s) < 500.0)  # still on the first straight
    final = trace.final
    assert tr.lane_of(final.d) == end_lane
    assert abs(final.d - tr.lane_centres[end_lane]) < 0.15
    assert abs(affordances(tr, final.s, final.d, final.heading)[0]) < 0.02
    assert ctrl.lane_changes_started == (lane != end_lane)
    if lane == end_lane:  # it corrects towards the centre, not away: never worse than the start, bar overshoot
        assert np.max(np.abs(d - tr.lane_centres[lane])) < abs(offset) + 0.3


@pytest.mark.parametrize("name", ["oval", "hairpins"])
@pytest.mark.parametrize("lanes", [1, 2, 3])
def test_full_lap_without_leaving_the_road(name, lanes):
    tr = track(name, lanes)
    ctrl = ChenController(lanes)
    start = VehicleState(s=0.0, d=tr.lane_centres[lanes // 2], heading=0.0, speed=15.0)
    travelled = []

    def lap_done(trace):
        if len(trace.s) > 1:
            travelled.append(float(tr.gap(trace.s[-2], trace.s[-1])))
        return sum(travelled) >= tr.length

    trace = drive(tr, ctrl, start, seconds=200.0, stop=lap_done)
    assert sum(travelled) >= tr.length, "did not finish the lap"
    d = np.asarray(trace.d)
    assert np.max(np.abs(d)) < tr.half_width
    # and in some lane's band all the way: never straddling the edge by more than a car's half width
    assert np.max(np.abs(d)) < tr.half_width - 1.0
    assert min(trace.speed[50:]) > 10.0  # no stalling in the bends


def warmed_controller(tr, lanes, start):
    """A controller that has cruised straight in an empty lane long enough (timer_set + 1 frames) for its
    occupancy timers to know the neighbour lanes are empty, as a host already driving at speed would."""
    ctrl = ChenController(lanes)
    feed(ctrl, affordances(tr, start.s, start.d, start.heading), 61, start.speed)
    assert ctrl.left_clear and ctrl.right_clear
    return ctrl


@pytest.mark.parametrize("lanes", [3, 2])
def test_overtakes_a_slow_car(lanes):
    tr = track("oval", lanes)
    lane = 1
    centre = tr.lane_centres[lane]
    start = VehicleState(s=20.0, d=centre, heading=0.0, speed=18.0)
    traffic = ScriptedTraffic(tr, s=[start.s + 40.0], d=[centre], speed=[8.0])
    ctrl = warmed_controller(tr, lanes, start)
    trace = drive(tr, ctrl, start, seconds=20.0, traffic=traffic)
    lanes_left = np.asarray(trace.lane)
    gap = np.asarray(trace.gaps)[:, 0]
    assert np.any(lanes_left != lane), "never changed lane"
    assert np.any(gap < 0), "never passed the slow car"
    assert not collided(trace)
    assert np.all(np.abs(trace.d) < tr.half_width)
    assert ctrl.lane_changes_started >= 1


def test_follows_when_all_lanes_blocked():
    tr = track("oval", 3)
    start = VehicleState(s=20.0, d=tr.lane_centres[1], heading=0.0, speed=14.0)
    traffic = ScriptedTraffic(tr, s=[start.s + 25.0] * 3, d=list(tr.lane_centres), speed=[8.0] * 3)
    ctrl = ChenController(3)
    trace = drive(tr, ctrl, start, seconds=25.0, traffic=traffic)
    gap = np.asarray(trace.gaps)[:, 1]
    assert ctrl.lane_changes_started == 0 and np.all(np.asarray(trace.lane) == 1)
    assert not collided(trace)
    assert gap.min() > 5.0
    # settles where the follow curve gives the leader's speed: 20 (1 - exp(-2.772/20 g + 0.693)) = 8
    g_eq = (0.693 - math.log(1 - 8 / 20)) * 20 / 2.772
    assert gap[-1] == pytest.approx(g_eq, abs=0.3)
    assert trace.speed[-1] == pytest.approx(8.0, abs=0.3)


def test_follow_law_keeps_5_m_from_a_fast_approach():
    tr = track("oval", 3)
    start = VehicleState(s=20.0, d=tr.lane_centres[1], heading=0.0, speed=18.0)
    traffic = ScriptedTraffic(tr, s=[start.s + 40.0] * 3, d=list(tr.lane_centres), speed=[8.0] * 3)
    trace = drive(tr, ChenController(3), start, seconds=15.0, traffic=traffic)
    gap = np.asarray(trace.gaps)[:, 1]
    # the follow law only starts braking at 15 m; with the host's 1.1 g brakes it stops short of 5 m
    assert gap.min() > 5.0
