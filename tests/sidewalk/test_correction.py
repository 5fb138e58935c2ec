"""The correction rule (controller/sidewalk/correction.py): when the expert takes over and when it hands back,
rule by rule, and correctional operation with the poor driver in the world."""
import numpy as np
import pytest

from controller.sidewalk import CorrectionRule, PoorDriver, SidewalkExpert, SidewalkMetrics
from drivestudio.worlds.sidewalk.drivers import Supervisor
from sim.sidewalk.world import SidewalkConfig, SidewalkWorld
from tests.sidewalk.helpers import record

SAME = ((0.5, 0.6), (0.5, 0.6))   # driver and expert agree


def test_calm_driving_is_left_alone():
    rule = CorrectionRule()
    for _ in range(100):
        assert not rule.update(record(speed=2.0), *SAME)


@pytest.mark.parametrize("fields, why", [
    ({"d": 0.95}, "leaving the path"),                                   # the body reaches over the edge
    ({"d": 0.7, "heading": 0.3, "speed": 2.0}, "about to leave the path"),  # will within half a second
    ({"speed": 2.0, "obstacle_gap": 1.0, "obstacle_d": 0.1, "obstacle_width": 0.3}, "nearing an obstacle"),
    ({"border_left": 0.04}, "nearing a border"),
    ({"lead_gap": 0.3}, "nearing the lead car"),
])
def test_a_hazard_takes_over_at_once(fields, why):
    rule = CorrectionRule()
    assert rule.update(record(**fields), *SAME) and rule.reason == why


def test_obstacles_beside_the_lane_or_far_enough_are_no_hazard():
    rule = CorrectionRule()
    assert not rule.update(record(speed=2.0, obstacle_gap=1.0, obstacle_d=0.7, obstacle_width=0.3), *SAME)
    assert not rule.update(record(speed=1.0, obstacle_gap=1.0, obstacle_d=0.0, obstacle_width=0.3), *SAME)


def test_deviating_from_the_expert_takes_over_only_when_it_lasts():
    rule = CorrectionRule()
    wrong = ((0.9, 0.6), (0.5, 0.6))
    for _ in range(rule.p.deviation_steps - 1):
        assert not rule.update(record(speed=2.0), *wrong)
    assert not rule.update(record(speed=2.0), *SAME)              # a moment's disagreement is forgiven
    for _ in range(rule.p.deviation_steps - 1):
        assert not rule.update(record(speed=2.0), *wrong)
    assert rule.update(record(speed=2.0), *wrong) and rule.reason == "deviating from the expert"


def test_a_car_that_stalls_where_the_expert_would_drive_is_taken_over():
    rule = CorrectionRule()
    stopped, expert_drives = record(speed=0.05), ((0.5, 0.52), (0.5, 0.66))   # motor 0.52 vs 0.66: within motor_dev
    steps = round(rule.p.stall_time / rule.dt)
    for _ in range(steps - 1):
        assert not rule.update(stopped, *expert_drives)
    assert rule.update(stopped, *expert_drives) and rule.reason == "stalled"
    patient = CorrectionRule()   # behind a stopped lead car the expert stops too: standing still is right
    for _ in range(3 * steps):
        assert not patient.update(stopped, (0.5, 0.5), (0.5, 0.5))


def test_hand_back_after_a_recovery():
    rule = CorrectionRule()
    assert rule.update(record(d=0.95), *SAME)
    steps = 0
    while rule.update(record(d=0.0, speed=2.0), *SAME):
        steps += 1
        assert steps < 200
    drove = (steps + 1) * rule.dt                                    # the take-over step and those after it
    assert drove == pytest.approx(max(rule.p.min_correction, rule.p.recovery))
    assert rule.update(record(d=0.95), *SAME)                       # and takes over again
    for _ in range(20):                                              # not recovered while it stays near the edge
        assert rule.update(record(d=0.8, speed=2.0), *SAME)
    for _ in range(int(rule.p.recovery / rule.dt) - 1):              # calm for a second, less one step
        assert rule.update(record(d=0.0, speed=2.0), *SAME)
    assert not rule.update(record(d=0.0, speed=2.0), *SAME)


def drive_poor(operation: str, seconds: float = 90.0):
    w = SidewalkWorld(SidewalkConfig(path="park", seed=2, mode="direct", render=False))
    poor, sup, m = PoorDriver(seed=4), Supervisor(w, operation), SidewalkMetrics(w.dt)
    obs = w.observe(False)
    for _ in range(int(seconds / w.dt)):
        applied, name = sup(obs, np.array(poor.act(obs.record)))
        obs = w.step(applied, False)
        m.update(obs.record)
        assert obs.truth["operation"] == ("autonomous", "correctional").index(name) + 1
        if obs.end is not None:
            break
    return m.report(), obs


def test_the_expert_keeps_the_poor_driver_safe():
    rep, obs = drive_poor("correctional")
    assert obs.end is None and rep["collisions"] == 0 and rep["off_path_time_s"] == 0.0
    assert rep["corrections"] >= 3 and 40.0 < rep["autonomy_percent"] < 95.0
    alone, last = drive_poor("autonomous")
    assert last.end is not None or alone["collisions"] > 0 or alone["off_path_time_s"] > 0   # without it: trouble


def test_corrected_steps_are_flagged_in_the_record():
    w = SidewalkWorld(SidewalkConfig(path="park", seed=2, render=False))
    sup = Supervisor(w, "correctional")
    obs = w.observe(False)
    far_off = np.array([0.0, 0.7])                                   # full left, fast: soon over the edge
    flags = []
    for _ in range(60):
        applied, name = sup(obs, far_off)
        obs = w.step(applied, False)
        flags.append((obs.truth["correcting"], obs.truth["operation"], name))
    assert flags[0] == (False, 1, "autonomous")
    assert any(f == (True, 2, "correctional") for f in flags)
    expert = SidewalkExpert()
    assert sup.expert.action(obs.record) == pytest.approx(expert.action(obs.record))
