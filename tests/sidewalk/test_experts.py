"""The experts of the three behavioural modes: clean driving, and visibly different driving in the same place."""
import numpy as np
import pytest

from controller.sidewalk import SidewalkExpert, SidewalkMetrics
from core.worlds.sidewalk import SIDEWALK
from sim.sidewalk.world import SidewalkConfig, SidewalkWorld

IX = {n: SIDEWALK.index(n) for n in SIDEWALK.truth_names}


def run(mode: str, seconds: float, path="park", seed: int = 3, obstacles=4.0):
    """(metrics report, records) of the mode's expert driving from the same start."""
    w = SidewalkWorld(SidewalkConfig(path=path, seed=seed, mode=mode, obstacles=obstacles, render=False))
    expert, m = SidewalkExpert(), SidewalkMetrics(w.dt)
    obs = w.observe(False)
    records = []
    for _ in range(int(round(seconds / w.dt))):
        obs = w.step(expert.action(obs.record), False)
        assert obs.end is None
        m.update(obs.record)
        records.append(obs.record)
    return m.report(), np.array(records)


@pytest.fixture(scope="module")
def drives():
    return {mode: run(mode, 90.0) for mode in ("direct", "follow", "furtive")}


def test_every_mode_drives_cleanly(drives):
    for mode, (rep, _) in drives.items():
        assert rep["collisions"] == 0 and rep["off_path_time_s"] == 0.0, mode
        assert rep["obstacles_met"] >= 3, mode          # and it met obstacles on the way


def test_direct_cruises_and_steers_round_obstacles(drives):
    rep, rec = drives["direct"]
    assert rep["mean_speed_mps"] > 2.3
    beside = rec[:, IX["obstacle_gap"]] < 0.0
    assert beside.sum() > 20
    # alongside an obstacle its body keeps at least 10 cm clear of it (centre to edge: half its width more)
    gap = np.abs(rec[beside, IX["d"]] - rec[beside, IX["obstacle_d"]]) - rec[beside, IX["obstacle_width"]] / 2
    assert (gap > 0.1 + 0.1).all()
    swerve = np.abs(rec[beside, IX["d"]]).max()
    assert swerve > 0.3                                              # it left the centre line to get by


def test_follow_keeps_an_even_distance_and_modulates_speed(drives):
    rep, rec = drives["follow"]
    assert rep["mean_lead_gap_m"] == pytest.approx(1.2, abs=0.2) and rep["lead_gap_std_m"] < 0.35
    speed = rec[:, IX["speed"]]
    assert speed.std() > 0.4                                      # its speed varies with the lead car's
    assert np.corrcoef(speed, rec[:, IX["lead_speed"]])[0, 1] > 0.8


def test_furtive_creeps_beside_borders_and_hurries_where_there_are_none(drives):
    rep, rec = drives["furtive"]
    _, direct = drives["direct"]
    bordered = np.minimum(rec[:, IX["border_left"]], rec[:, IX["border_right"]]) < 5.0
    open_ = ~bordered
    assert bordered.any() and open_.any()
    free = open_ & (rec[:, IX["obstacle_gap"]] > 4)
    assert rec[bordered, IX["speed"]].mean() < 1.2 < 2.5 < rec[free, IX["speed"]].max()
    nearer = lambda r: np.minimum(r[:, IX["border_left"]], r[:, IX["border_right"]])   # noqa: E731
    d_bordered = np.minimum(direct[:, IX["border_left"]], direct[:, IX["border_right"]]) < 5.0
    assert nearer(rec)[bordered].mean() < nearer(direct)[d_bordered].mean() - 0.3   # much closer than direct
    assert rep["mean_speed_mps"] < drives["direct"][0]["mean_speed_mps"] - 0.8


def test_the_same_place_three_ways(drives):
    """From the same start, the three modes are three different trajectories."""
    d = {mode: rec[:300, IX["d"]] for mode, (_, rec) in drives.items()}
    s = {mode: rec[:300, IX["speed"]] for mode, (_, rec) in drives.items()}
    assert np.abs(d["furtive"]).mean() > np.abs(d["direct"]).mean() + 0.3
    assert abs(s["follow"].mean() - s["direct"].mean()) > 0.5


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["direct", "follow", "furtive"])
def test_ten_minutes_on_a_procedural_loop_with_obstacles(mode):
    rep, _ = run(mode, 600.0, path="procedural:11", seed=5, obstacles=5.0)
    assert rep["collisions"] == 0 and rep["off_path_time_s"] == 0.0
    assert rep["obstacles_met"] >= 20


def test_near_an_obstacle_the_expert_passes_on_the_side_the_car_is_on():
    """Where crossing to the cheaper side would mean cutting across the obstacle's front in the last metres (a car the
    expert takes over from wherever a driver left it), it passes on the car's own side."""
    from tests.sidewalk.helpers import record
    expert = SidewalkExpert()
    near = record(d=0.47, heading=0.1, speed=2.9, path_width=2.12, obstacle_gap=0.9, obstacle_d=0.32,
                  obstacle_width=0.5)
    assert expert.around_obstacle(near, 0.0) > 0.32 + 0.25               # left of it, where the car is
    far = record(d=0.47, heading=0.1, speed=2.9, path_width=2.12, obstacle_gap=6.0, obstacle_d=0.32,
                 obstacle_width=0.5)
    assert expert.around_obstacle(far, 0.0) == 0.0                       # far away it does not swerve yet
    rightish = record(d=0.2, path_width=2.12, obstacle_gap=0.9, obstacle_d=0.32, obstacle_width=0.5)
    assert expert.around_obstacle(rightish, 0.0) < 0.32 - 0.25           # right of its centre: passes right


def test_the_swerve_round_an_obstacle_is_an_arc_then_a_straight():
    """swerve_distance: the reaction (0.15 s), an arc of radius max(1 m, v^2 / 2.5 m/s^2) up to 1 rad from the
    path's heading, then straight on at that angle."""
    import math

    from controller.sidewalk.experts import REACTION, swerve_distance
    assert swerve_distance(3.0, 0.0) == 0.0 and swerve_distance(3.0, -0.2) == 0.0          # clear already
    lateral = 1 - math.cos(0.5)                                                             # radius 1 m at 1 m/s
    assert swerve_distance(1.0, lateral) == pytest.approx(REACTION + math.sin(0.5))
    r = 9.0 / 2.5                                                                           # 3 m/s: 3.6 m
    assert swerve_distance(3.0, r * (1 - math.cos(0.3))) == pytest.approx(3 * REACTION + r * math.sin(0.3))
    beyond = swerve_distance(1.0, 1.0)                                                      # arc to 1 rad, then on
    assert beyond == pytest.approx(REACTION + math.sin(1.0) + (1.0 - (1 - math.cos(1.0))) / math.tan(1.0))
    assert swerve_distance(1.0, 0.3, heading=0.4) < swerve_distance(1.0, 0.3) < swerve_distance(1.0, 0.3, -0.4)


def test_a_car_clear_of_an_obstacle_but_closing_on_it_needs_the_way_it_takes_to_turn_parallel():
    """Clear by a millimetre at 2.9 m/s, 0.08 rad towards it: the reaction and the arc back to the path's heading
    (radius 2.9^2 / 2.5 m); clear by half a metre, or heading away, it needs nothing."""
    import math

    from controller.sidewalk.experts import REACTION, swerve_distance
    r = 2.9 ** 2 / 2.5
    assert swerve_distance(2.9, -0.001, heading=-0.08) == pytest.approx(2.9 * REACTION + r * math.sin(0.08))
    assert swerve_distance(2.9, -0.5, heading=-0.08) == 0.0
    assert swerve_distance(2.9, -0.001, heading=0.08) == 0.0


def test_a_car_squeezed_beside_an_obstacle_is_steered_away_from_it_not_across_it():
    from tests.sidewalk.helpers import SQUEEZED, record
    expert = SidewalkExpert()
    squeezed = record(**SQUEEZED)
    assert expert.around_obstacle(squeezed, 0.0) > SQUEEZED["d"]           # its own side, farther from it
    steer, _, _ = expert.act(squeezed, "direct")
    assert steer < 0.5                                                      # left: away from the obstacle
    mirrored = record(**{**SQUEEZED, **{k: -SQUEEZED[k] for k in ("d", "heading", "curvature_ahead", "obstacle_d")},
                         "steer": 1 - SQUEEZED["steer"], "border_left": 5.0, "border_right": 0.355})
    assert expert.act(mirrored, "direct")[0] > 0.5                          # and right where it is on the right


def test_an_expert_taken_over_late_swerves_at_once_sharply_and_slowly():
    from tests.sidewalk.helpers import record
    expert = SidewalkExpert()
    late = record(speed=3.0, obstacle_gap=1.2, obstacle_d=0.05, obstacle_width=0.4, curvature_ahead=0.0)
    early = record(speed=3.0, obstacle_gap=3.8, obstacle_d=0.05, obstacle_width=0.4, curvature_ahead=0.0)
    assert expert.urgent(late) and not expert.urgent(early)
    steer, motor, why = expert.act(late, "direct")
    assert why == "swerving round an obstacle" and motor <= 0.5 + 1.0 / 18 + 1e-9           # 1 m/s at most
    assert steer > 0.8                                                                      # hard right: it is left
    assert abs(expert.act(early, "direct")[0] - 0.5) < 0.1                                  # early: a gentle start


def test_the_expert_keeps_its_side_of_a_lead_car_alongside():
    """The study's contact while correcting in follow mode: a network drew level with the lead car on its left and
    the expert, steering back to the path's centre, drove into it. Alongside, the expert keeps its own side."""
    from tests.sidewalk.helpers import record
    expert = SidewalkExpert()
    left_of_it = record(d=0.6, heading=0.0, speed=2.0, lead_gap=-0.5, lead_d=0.26, lead_speed=1.2)
    assert expert.beside_lead(left_of_it, 0.0) >= 0.26 + 0.2
    assert expert.act(left_of_it, "follow")[0] <= 0.5 + 1e-9                      # not to the right, into it
    right_of_it = record(d=-0.6, heading=0.0, speed=2.0, lead_gap=-0.5, lead_d=-0.26, lead_speed=1.2)
    assert expert.act(right_of_it, "follow")[0] >= 0.5 - 1e-9
    ahead = record(d=0.6, speed=2.0, lead_gap=1.5, lead_d=0.26, lead_speed=1.2)
    assert expert.beside_lead(ahead, 0.0) == 0.0                                  # ahead: it follows, as before
