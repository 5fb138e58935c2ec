"""A lane change's collision is told apart by rule 1 on the true gaps (docs/benchmark.md, crash clips): "blind spot"
when the true gaps had kept the target lane clear as long as rule 1 asks too, "misread" when they had a car ahead
in it; the shadow's rule 1 on the truth restarts whenever the driver's does."""
from types import SimpleNamespace

import numpy as np

from controller.highway import ChenController
from core.worlds.highway import HIGHWAY, INACTIVE, INDICATORS
from drivestudio.worlds.highway.benchmark.clips import Entry, ShadowController, fault
from drivestudio.worlds.highway.benchmark.score import collision_causes

ESTIMATE = HIGHWAY.estimate_names
NO_CAR_BEHIND = [100.0, 100.0, 0.0, 0.0]   # dist_LB, dist_RB, closing_LB, closing_RB


def left_lane_of_two(**given) -> np.ndarray:
    """The 14 indicators of a car at the centre of the left lane of a two-lane road (4 m lanes), road clear."""
    v = {"angle": 0.0, **INACTIVE, "fast": 0.0, "toMarking_ML": -2.0, "toMarking_MR": 2.0, "toMarking_RR": 6.0,
         "dist_MM": 60.0, "dist_RR": 60.0, **given}
    return np.array([v[n] for n in INDICATORS])


def step(t: float, truth: np.ndarray, estimate: np.ndarray):
    record = np.zeros(len(HIGHWAY.truth_names))
    record[HIGHWAY.index("lanes")], record[HIGHWAY.index("speed")] = 2, 15.0
    est = np.full(len(ESTIMATE), np.nan)
    est[:len(INDICATORS)] = estimate
    obs = SimpleNamespace(t=t, record=record, truth=SimpleNamespace(indicators=truth, rear=np.array(NO_CAR_BEHIND),
                                                                    speed=15.0))
    return SimpleNamespace(obs=obs, estimate=est, action=np.zeros(3))


def drive(truth: np.ndarray, estimate: np.ndarray, frames: int = 70) -> list[Entry]:
    shadow = ShadowController()
    entries = []
    for i in range(frames):
        rec = step(0.1 * i, truth, estimate)
        entries.append(Entry(rec.obs, rec.action, rec.estimate, shadow(rec)))
    return entries


def test_a_change_the_true_gaps_allowed_too_is_the_controllers_blind_spot():
    clear = left_lane_of_two()
    entries = drive(clear, clear)
    start = next(e for e in entries if e.control["state"] == "right-1")   # rule 3: back to the right lane
    assert start.control["truth_clear_frames"] == [61, 60]
    text, cause = fault(entries, 0.1)
    assert text.startswith("rule 3 (lane preference)") and cause == "blind spot"


def test_a_change_into_a_car_the_truth_saw_ahead_is_a_misread():
    entries = drive(left_lane_of_two(dist_RR=10.0), left_lane_of_two())   # a car 10 m ahead on the right, read free
    start = next(e for e in entries if e.control["state"] == "right-1")
    assert start.control["truth_clear_frames"] == [0, 60]
    assert fault(entries, 0.1)[1] == "misread"


def test_the_truths_rule_1_restarts_with_the_drivers():
    """After a change both lanes prove clear afresh on the truth too: the driver's restart is mirrored."""
    shadow = ShadowController()
    clear = left_lane_of_two()
    for i in range(61):                       # the change starts on the 61st frame (rule 1: more than 60)
        shadow(step(0.1 * i, clear, clear))
    assert shadow.ctrl is not None and shadow.ctrl.state == "right-1"
    assert shadow.truth_occupancy is not None and shadow.truth_occupancy.right == 0
    assert shadow.truth_occupancy.restarts == shadow.ctrl.occupancy.restarts == 1


def test_no_change_in_the_seconds_before_is_keeping():
    entries = drive(left_lane_of_two(dist_MM=8.0, dist_RR=10.0), left_lane_of_two(dist_MM=8.0, dist_RR=10.0), 30)
    assert fault(entries, 0.1)[1] == "keeping"


def test_a_controller_counts_its_restarts():
    ctrl = ChenController(2)
    for _ in range(61):
        ctrl.act(left_lane_of_two(), 15.0)
    assert ctrl.state == "right-1" and ctrl.occupancy.restarts == 1 and ctrl.occupancy.right == 0


def test_the_leaderboard_counts_collisions_by_cause_and_skips_off_road_clips():
    rows = [{"clips": [{"event": "collision", "cause": "blind spot"}, {"event": "off-road"},
                       {"event": "collision", "cause": "misread"}]},
            {"clips": [{"event": "collision", "cause": "blind spot"}, {"event": "collision", "cause": ""}]}]
    assert collision_causes(rows) == {"blind spot": 2, "misread": 1, "keeping": 0, "unknown": 1}
