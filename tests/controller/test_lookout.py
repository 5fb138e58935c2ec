"""The lookout controller, one test per rule of docs/controller.md's "The lookout" (L1-L3), with the numbers
written out from the document (min_gap 5 m, crossing_distance 14 m, min_crossing_time 0.7 s, margin_time 0.7 s,
follower_decel 4 m/s^2, ahead_min 10 m, clear_margin 0.3 m), and closed loops on the kinematic car that the paper's
controller crashes in.

Most frames follow a car 10 m ahead at V = 9.9993 m/s, the follow curve's speed there (20 (1 - exp(-2.772/20 10 +
0.693))), so that L3 takes nothing off the host's speed and the closing speeds are the labels' own; the host then
crosses in 14 / V = 1.4 s, so L1 allows 2.1 s of closing and L2 1.4 s."""
import math
from dataclasses import replace

import numpy as np
import pytest

from controller.highway import ChenController
from controller.highway.lookout import LookoutController, LookoutParams, crossing, safe_gap
from core.worlds.highway import Action
from sim.highway.traffic import ScriptedTraffic
from sim.highway.truth import affordances
from sim.highway.vehicle import VehicleState, step_vehicle
from sim.track import load_track
from tests.controller.drive_helpers import collided, drive
from tests.controller.test_chen import feed, in_lane, ind

NOTHING = (100.0, 100.0, 0.0, 0.0)   # dist_LB, dist_RB, closing_LB, closing_RB of an empty road
V = 20 * (1 - math.exp(-2.772 / 20 * 10 + 0.693))   # [m/s] the follow speed at 10 m: 9.9993
T1, T2 = 14 / V + 0.7, 14 / V   # [s] L1's and L2's closing times at V


def need(c, time):
    """The document's safe gap, written out."""
    c = max(c, 0.0)
    return 5 + c * time + c * c / 8


def rear(dist_LB=100.0, dist_RB=100.0, closing_LB=0.0, closing_RB=0.0):
    return (dist_LB, dist_RB, closing_LB, closing_RB)


def warm(lanes=3, lane=1, behind=NOTHING, **given):
    """A lookout controller that has driven 61 frames in `lane`: both neighbour lanes proved clear (rule 1)."""
    ctrl = LookoutController(lanes)
    for _ in range(61):
        ctrl.act(in_lane(lanes=lanes, lane=lane, **given), 15.0, behind)
    return ctrl


def test_the_lookout_holds_the_documented_constants():
    p = LookoutParams()
    assert (p.min_gap, p.crossing_distance, p.min_crossing_time, p.margin_time, p.follower_decel, p.ahead_min,
            p.clear_margin, p.coe_phase_2) == (5.0, 14.0, 0.7, 0.7, 4.0, 10.0, 0.3, 1.5)


def test_crossing_takes_14_m_of_road_but_never_less_than_0_7_s():
    assert crossing(7.0) == pytest.approx(2.0) and crossing(14.0) == pytest.approx(1.0)
    assert crossing(20.0) == crossing(28.0) == 0.7 and crossing(0.0) == pytest.approx(28.0)


@pytest.mark.parametrize("closing, expected", [(-8.0, 5.0), (0.0, 5.0), (4.0, 5 + 4 * 1.7 + 2), (10.0, 5 + 17 + 12.5)])
def test_safe_gap_is_min_gap_plus_the_closing_during_the_crossing_plus_the_followers_braking(closing, expected):
    assert safe_gap(closing, 14.0) == pytest.approx(expected)                 # crossing 1 s, + 0.7 s margin
    assert safe_gap(closing, 14.0, abort=True) == pytest.approx(expected - 0.7 * max(closing, 0.0))
    assert safe_gap(closing, 7.0) == pytest.approx(need(closing, 2.7))       # a slower host crosses longer


@pytest.mark.parametrize("speed", [3.0, 4.0, 8.0, 12.0, 16.0, 20.0, 24.0])
def test_crossing_is_what_the_chen_controllers_change_takes_on_the_kinematic_car(speed):
    """crossing(v) is measured: from begin_lane_change until the host's centre is across the marking, at a speed
    held constant (L3 may hold it), the host covers 13-14 m of road; above 20 m/s the steering rate caps it. The
    lookout's own change (L4's stronger phase 2) is no slower."""
    tr = load_track("oval", lanes=3)
    for ctrl in (ChenController(3), LookoutController(3)):
        state = VehicleState(s=50.0, d=float(tr.lane_centres[1]), speed=speed)
        ctrl.begin_lane_change("left")
        t = 0.0
        while state.d < tr.markings[1]:
            a = ctrl.act(affordances(tr, state.s, state.d, state.heading), state.speed)
            state = replace(step_vehicle(state, Action(a.steer, 0.0, 0.0), 0.1, tr), speed=speed)
            t += 0.1
        assert t <= crossing(speed) + 0.1 + 1e-9
        if isinstance(ctrl, ChenController) and not isinstance(ctrl, LookoutController):
            assert crossing(speed) - 0.3 <= t


def test_with_nothing_beside_or_behind_it_steers_as_the_chen_controller():
    """L1 and L2 never act on an empty road; L3 changes the speed only during a lane change (and L4 the steering
    only in phase 2, which these in-lane frames never reach)."""
    chen, look = ChenController(3), LookoutController(3)
    vectors = [in_lane(offset=0.3 * np.sin(i / 7), dist_MM=30 - i / 5, angle=0.02 * np.cos(i / 5))
               for i in range(150)]
    for v in vectors:
        a, b = chen.act(v, 15.0), look.act(v, 15.0, NOTHING)
        assert a.steer == b.steer and chen.state == look.state
        if chen.state == "keep":
            assert a == b
    assert chen.lane_changes_started == look.lane_changes_started >= 1 and look.refusals == look.aborts == 0


# --- L1: look before moving ---------------------------------------------------------------------------------------
def test_L1_refuses_an_overtake_to_the_left_into_a_car_within_the_safe_gap_and_goes_right():
    ctrl = warm()
    ctrl.act(in_lane(dist_MM=10.0), V, rear(dist_LB=need(4, T1) - 0.01, closing_LB=4.0))   # 15.4 m
    assert ctrl.state == "right-1" and ctrl.refusals == 1
    ctrl = warm()
    ctrl.act(in_lane(dist_MM=10.0), V, rear(dist_LB=need(4, T1) + 0.01, closing_LB=4.0))
    assert ctrl.state == "left-1" and ctrl.refusals == 0


def test_L1_refuses_both_sides_then_the_host_follows():
    ctrl = warm()
    a = ctrl.act(in_lane(dist_MM=10.0, fast=1.0), V, rear(dist_LB=0.0, dist_RB=4.9))   # alongside; 4.9 < 5
    assert ctrl.state == "keep" and ctrl.refused == "right" and ctrl.refusals == 2
    assert (a.accel, a.brake) == (pytest.approx(0.2), 0.0)   # the follow law: 10 m/s, accel 0.2 (10 - 10 + 1)
    ctrl.act(in_lane(dist_MM=10.0), V, rear(dist_LB=0.0, dist_RB=5.0, closing_RB=-3.0))
    assert ctrl.state == "right-1"   # a slower car 5 m behind: min_gap is enough


def test_L1_a_faster_car_far_behind_needs_more_than_a_slower_one_near():
    ctrl = warm(dist_RR=12.0)
    ctrl.act(in_lane(dist_MM=10.0, dist_RR=12.0), V, rear(dist_LB=38.4, closing_LB=10.0))   # needs 38.5
    assert ctrl.state == "keep" and ctrl.refused == "left"
    ctrl.act(in_lane(dist_MM=10.0, dist_RR=12.0), V, rear(dist_LB=38.6, closing_LB=10.0))
    assert ctrl.state == "left-1"


def test_L1_counts_the_speed_L3_will_take_off_the_host():
    """At 14 m/s (V + 4) behind a car 10 m ahead, L3 will hold the host to V during the change: a car behind at
    +2 m/s will close at 6 m/s while the host takes 1.4 s to cross, so it needs 5 + 6 x 2.1 + 4.5 = 22.1 m, not
    the 5 + 2 x 1.7 + 0.5 = 8.9 m of a host that kept 14 m/s."""
    ctrl = warm(dist_RR=12.0)
    ctrl.act(in_lane(dist_MM=10.0, dist_RR=12.0), V + 4.0, rear(dist_LB=need(6, T1) - 0.01, closing_LB=2.0))
    assert ctrl.state == "keep" and ctrl.refused == "left"
    ctrl.act(in_lane(dist_MM=10.0, dist_RR=12.0), V + 4.0, rear(dist_LB=need(6, T1) + 0.01, closing_LB=2.0))
    assert ctrl.state == "left-1"


def test_L1_applies_to_lane_preference_too():
    ctrl = LookoutController(2)   # two lanes: keep right (rule 3)
    left = in_lane(lanes=2, lane=0)
    for _ in range(61):
        ctrl.act(left, 20.0, rear(dist_RB=0.0, closing_RB=0.5))   # a car alongside in the right lane
    assert ctrl.right_clear and ctrl.state == "keep" and ctrl.refused == "right"
    ctrl.act(left, 20.0, rear(dist_RB=9.0, closing_RB=-1.0))
    assert ctrl.state == "right-1"


# --- L2: abort until the centre crosses -----------------------------------------------------------------------------
def test_L2_aborts_in_phase_1_and_keeps_its_lane():
    ctrl = warm()
    ctrl.act(in_lane(dist_MM=10.0), V, NOTHING)
    assert ctrl.state == "left-1"
    ctrl.act(in_lane(offset=0.5), V, rear(dist_LB=10.4, closing_LB=3.0))   # L1 would need 12.4, L2 10.33
    assert ctrl.state == "left-1" and ctrl.aborts == 0
    s = ctrl.act(in_lane(offset=0.8), V, rear(dist_LB=10.4, closing_LB=3.1)).steer   # L2 needs 10.54
    assert ctrl.state == "keep" and ctrl.aborts == 1
    assert s == pytest.approx(-0.8 / 8 / 0.541052 / 1.5)   # lane keeping steers back to the lane centre
    assert not ctrl.left_clear and not ctrl.right_clear     # both lanes prove clear afresh


def test_L2_aborts_on_the_marking_before_the_centre_crosses_it():
    ctrl = warm()
    ctrl.act(in_lane(dist_MM=10.0), V, NOTHING)
    ctrl.act(ind(toMarking_L=-4.2, toMarking_M=-0.2, toMarking_R=3.8, dist_L=60.0, dist_R=10.0), V, NOTHING)
    assert ctrl.state == "left-2"
    s = ctrl.act(ind(toMarking_L=-4.1, toMarking_M=-0.1, toMarking_R=3.9, dist_L=60.0, dist_R=10.0), V,
                 rear(dist_LB=0.0, closing_LB=2.0)).steer
    # the mirror change's phase 2 aims at the lane right of the marking, (R + M) / 2, with L4's gain 1.5
    assert ctrl.state == "right-2" and ctrl.aborts == 1
    assert s == pytest.approx(max(-1.0, -((3.9 - 0.1) / 2) / 8 / 0.541052 / 1.5))


def test_L2_does_not_abort_once_the_centre_has_crossed():
    ctrl = warm()
    ctrl.act(in_lane(dist_MM=10.0), 15.0, NOTHING)
    ctrl.act(ind(toMarking_L=-4.2, toMarking_M=-0.2, toMarking_R=3.8), 15.0, NOTHING)
    ctrl.act(ind(toMarking_L=-3.9, toMarking_M=0.1, toMarking_R=4.1), 15.0, rear(dist_LB=0.0, closing_LB=9.0))
    assert ctrl.state == "left-2" and ctrl.aborts == 0


def test_L2_aborts_for_a_car_closer_than_10_m_ahead_in_the_target_lane():
    ctrl = warm()
    ctrl.act(in_lane(dist_MM=10.0), 15.0, NOTHING)
    ctrl.act(in_lane(offset=0.5, dist_LL=10.0), 15.0, NOTHING)
    assert ctrl.state == "left-1"
    ctrl.act(in_lane(offset=0.7, dist_LL=9.9), 15.0, NOTHING)
    assert ctrl.state == "keep" and ctrl.aborts == 1


def test_L2_a_right_change_mirrors_a_left_one():
    ctrl = warm(dist_LL=12.0)
    ctrl.act(in_lane(dist_MM=10.0, dist_LL=12.0), 15.0, NOTHING)
    assert ctrl.state == "right-1"
    ctrl.act(ind(toMarking_L=-3.8, toMarking_M=0.2, toMarking_R=4.2), 15.0, NOTHING)
    assert ctrl.state == "right-2"
    ctrl.act(ind(toMarking_L=-3.9, toMarking_M=0.1, toMarking_R=4.1), 15.0, rear(dist_RB=3.0))
    assert ctrl.state == "left-2" and ctrl.aborts == 1


# --- L3: pull out behind the leader -------------------------------------------------------------------------------
def test_L3_holds_the_follow_speed_of_the_leader_until_laterally_clear():
    ctrl, chen = warm(), ChenController(3)
    feed(chen, in_lane(), 61)
    for c in (ctrl, chen):
        a = c.act(in_lane(dist_MM=9.0, fast=1.0), 12.0, NOTHING) if c is ctrl else \
            c.act(in_lane(dist_MM=9.0, fast=1.0), 12.0)
        assert c.state == "left-1"
        if c is chen:
            assert a.accel == pytest.approx(1.0) and a.brake == 0.0   # the paper's driver: full throttle
        else:   # follow curve at 9 m: 20 (1 - exp(-2.772 / 20 * 9 + 0.693)) = 8.51 m/s: it brakes
            assert a.accel == 0.0 and a.brake == pytest.approx(0.1 * (12 - 8.5093), abs=1e-3)
    on_marking = dict(toMarking_L=-4.2, toMarking_M=-0.2, toMarking_R=3.8, dist_L=60.0, dist_R=9.0, fast=1.0)
    a = ctrl.act(ind(**on_marking), 12.0, NOTHING)      # on the marking: the leader is in the lane right of it
    assert ctrl.state == "left-2" and a.brake > 0
    a = ctrl.act(ind(**{**on_marking, "toMarking_M": 0.29, "toMarking_L": -3.71}), 12.0, NOTHING)
    assert a.brake > 0                                    # 0.29 m past the marking: not yet clear
    a = ctrl.act(ind(**{**on_marking, "toMarking_M": 0.31, "toMarking_L": -3.69}), 12.0, NOTHING)
    assert a.accel > 0 and a.brake == 0                   # clear: free to accelerate


# --- L4: cross at lane keeping's gain --------------------------------------------------------------------------------
def test_L4_phase_2_steers_with_lane_keepings_gain_not_20():
    ctrl, chen = warm(), ChenController(3)
    feed(chen, in_lane(), 61)
    on_marking = ind(toMarking_L=-4.2, toMarking_M=-0.2, toMarking_R=3.8)
    for c in (ctrl, chen):
        c.act(in_lane(dist_MM=10.0), V, NOTHING) if c is ctrl else c.act(in_lane(dist_MM=10.0), V)
    s_look = ctrl.act(on_marking, V, NOTHING).steer
    s_chen = chen.act(on_marking, V).steer
    assert ctrl.state == chen.state == "left-2"
    assert s_chen == pytest.approx(2.2 / 8 / 0.541052 / 20) and s_look == pytest.approx(2.2 / 8 / 0.541052 / 1.5)


def bend(turn: str):
    """Two 4 m lanes; the host enters a 60 m arc turning `turn` (half circles joined by 100 m straights)."""
    from sim.track import track_from_spec
    arc = {"type": "arc", "radius": 60, "angle_deg": 180, "turn": turn}
    return track_from_spec({"name": "bend", "lanes": 2, "lane_width": 4.0, "segments": [
        {"type": "straight", "length": 100}, arc, {"type": "straight", "length": 100}, arc]})


@pytest.mark.parametrize("speed", [8.0, 14.0, 20.0])
def test_L4_a_change_to_the_inside_of_a_tight_bend_completes(speed):
    """On a 60 m bend the paper's phase 2 (coe 20) cannot turn with the road and the host drifts back across the
    marking; the lookout's change ends in the target lane (speed held, the controller steering)."""
    tr = bend("left")
    results = {}
    for name, ctrl in (("chen", ChenController(2)), ("lookout", LookoutController(2))):
        state = VehicleState(s=110.0, d=float(tr.lane_centres[1]), speed=speed)
        ctrl.begin_lane_change("left")
        for _ in range(100):
            a = ctrl.act(affordances(tr, state.s, state.d, state.heading), state.speed)
            state = replace(step_vehicle(state, Action(a.steer, 0.0, 0.0), 0.1, tr), speed=speed)
            if ctrl.state == "keep":
                break
        results[name] = (ctrl.state, tr.lane_of(state.d))
    assert results["lookout"] == ("keep", 0)
    assert results["chen"] != ("keep", 0)


# --- closed loop on the kinematic car -----------------------------------------------------------------------------
def overtaking_scene(controller, behind_speed, behind):
    """Two lanes, the host in the right lane at 15 m/s closing on a car at 8 m/s 30 m ahead; in the left lane a
    car `behind` [m] behind the host at `behind_speed`, which the paper's indicators cannot see until it is ahead.
    Scripted cars keep their speed: nothing brakes for the host."""
    tr = load_track("oval", lanes=2)
    start = VehicleState(s=20.0, d=float(tr.lane_centres[1]), speed=15.0)
    warmup = ScriptedTraffic(tr, s=[], d=[], speed=[])
    drive(tr, controller, start, 6.2, traffic=warmup)   # 61 frames alone: both lanes proved clear
    traffic = ScriptedTraffic(tr, s=[start.s + 30.0, start.s - behind], d=[tr.lane_centres[1], tr.lane_centres[0]],
                              speed=[8.0, behind_speed])
    return drive(tr, controller, start, 20.0, traffic=traffic)


SCENES = [(19.0, 5.0), (22.0, 10.0), (22.0, 20.0), (25.0, 30.0), (28.0, 40.0)]   # the paper's driver crashes in each


@pytest.mark.parametrize("behind_speed, behind", SCENES)
def test_closed_loop_the_chen_controller_pulls_out_into_a_faster_car_from_behind(behind_speed, behind):
    assert collided(overtaking_scene(ChenController(2), behind_speed, behind))


@pytest.mark.parametrize("behind_speed, behind", SCENES + [(19.0, 20.0), (15.0, 10.0)])
def test_closed_loop_the_lookout_lets_it_pass_then_overtakes(behind_speed, behind):
    ctrl = LookoutController(2)
    trace = overtaking_scene(ctrl, behind_speed, behind)
    assert not collided(trace)
    gaps = np.asarray(trace.gaps)
    assert np.any(gaps[:, 0] < 0), "never passed the slow car"
    assert np.all(np.abs(trace.d) < 4.0)
