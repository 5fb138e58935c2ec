"""The lookout's L5, stop in time (docs/controller.md): the speed from which the host stops behind the car ahead should
that car brake to a standstill, with the numbers of the document (stop_decel 6 m/s^2, stop_delay 0.3 s, lead_decel
8 m/s^2, car_length 4.8 m, stop_margin 2 m, gap_jump 3 m, stop_gain 0.5), and a closed loop on the kinematic car."""
import math

import numpy as np
import pytest

from controller.highway.lookout import LookoutController, LookoutParams
from sim.highway.traffic import ScriptedTraffic
from sim.highway.vehicle import VehicleState
from sim.track import load_track
from tests.controller.drive_helpers import collided, drive
from tests.controller.test_chen import in_lane

STOP = LookoutParams(stop_in_time=True)


def limit(gap, lead):
    """The document's L5 limit, written out."""
    room = gap - 4.8 - 2.0 + lead * lead / 16.0
    return 0.0 if room <= 0 else 6.0 * (-0.3 + math.sqrt(0.09 + 2 * room / 6.0))


def test_l5_holds_the_documented_constants_and_is_off_unless_asked_for():
    p = LookoutParams()
    assert (p.stop_in_time, p.frame, p.stop_decel, p.stop_delay, p.lead_decel, p.car_length, p.stop_margin,
            p.gap_jump, p.stop_gain) == (False, 0.1, 6.0, 0.3, 8.0, 4.8, 2.0, 3.0, 0.5)
    plain, stopping = LookoutController(1), LookoutController(1, lookout=STOP)
    far = in_lane(lanes=1, lane=0, dist_MM=40.0)
    assert plain.act(far, 20.0) == LookoutController(1).act(far, 20.0) and plain.stop_limit == math.inf
    stopping.act(far, 20.0)
    assert stopping.stop_limit == pytest.approx(limit(40.0, 20.0))


@pytest.mark.parametrize("gaps, speed, lead", [((30.0, 29.0), 20.0, 10.0), ((25.0, 25.0), 15.0, 15.0),
                                               ((40.0, 30.0), 20.0, 20.0)])
def test_the_limit_is_the_stopping_speed_for_the_lead_speed_read_from_the_gaps_change(gaps, speed, lead):
    """29 m after 30 m at 20 m/s: closing 10 m/s, the car ahead drives 10 m/s; a 10-m jump is another car, whose
    speed is taken as the host's until the next frame."""
    ctrl = LookoutController(1, lookout=STOP)
    for gap in gaps:
        ctrl.act(in_lane(lanes=1, lane=0, dist_MM=gap), speed)
    assert ctrl.stop_limit == pytest.approx(limit(gaps[-1], lead))


def test_above_the_limit_it_brakes_with_stop_gain_and_without_a_car_ahead_not_at_all():
    ctrl = LookoutController(1, lookout=STOP)
    ctrl.act(in_lane(lanes=1, lane=0, dist_MM=20.0), 20.0)
    action = ctrl.act(in_lane(lanes=1, lane=0, dist_MM=18.0), 20.0)   # closing 20 m/s: a car standing still
    assert action.accel == 0 and action.brake == pytest.approx(min(1.0, 0.5 * (20.0 - limit(18.0, 0.0))))
    assert LookoutController(1, lookout=STOP).act(in_lane(lanes=1, lane=0), 20.0).brake == 0


@pytest.mark.parametrize("stopped_at", [60.0, 120.0])
def test_the_host_stops_behind_a_car_standing_in_its_only_lane_where_chens_follow_law_runs_into_it(stopped_at):
    track = load_track("oval", lanes=1)
    standing = ScriptedTraffic(track, [stopped_at], [0.0], [0.0])
    trace = drive(track, LookoutController(1, lookout=STOP), VehicleState(speed=20.0), 20.0, standing)
    gaps = np.asarray(trace.gaps)[:, 0]
    assert not collided(trace) and trace.final.speed < 0.1
    assert gaps.min() - 4.6 >= 1.0                          # a bumper gap of about stop_margin is left
    plain = drive(track, LookoutController(1), VehicleState(speed=20.0), 20.0,
                  ScriptedTraffic(track, [stopped_at], [0.0], [0.0]))
    assert collided(plain)
