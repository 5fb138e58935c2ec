"""The correction rules (controller/sidewalk/correction.py): each clause takes over where it should and not
elsewhere, under both rules (`safety`, the default, and `strict`); hand-back after a recovery; the tally by clause;
and correctional operation in the world: the expert keeps a poor driver safe and never collides while it holds the
wheel."""
import numpy as np
import pytest

from controller.sidewalk import CorrectionRule, PoorDriver, SidewalkExpert, SidewalkMetrics
from controller.sidewalk.correction import COLLISION, DEVIATING, LEAVING, RULES, STALLED, check_rule, foresee
from controller.sidewalk.experts import swerve_needed
from controller.sidewalk.poor import PoorParams
from drivestudio.worlds.sidewalk.drivers import Supervisor
from sim.sidewalk.world import SidewalkConfig, SidewalkWorld
from tests.sidewalk.helpers import SQUEEZED, record

SAME = ((0.5, 0.6), (0.5, 0.6))   # driver and expert agree: straight on at about 1.8 m/s
WILD = PoorParams(bias_sigma=0.2, lapse_every=(2.0, 5.0), lapse_length=(1.0, 3.0), speed_factor=1.6)


def takes_over(rule: str, rec, driver=(0.5, 0.6), expert=(0.5, 0.6), steps: int = 1) -> str | None:
    """The reason `rule` takes over within `steps` steps of the same record and commands, or None."""
    r = CorrectionRule(rule=rule)
    for _ in range(steps):
        if r.update(rec, driver, expert):
            return r.reason
    return None


@pytest.mark.parametrize("rule", RULES)
def test_calm_driving_is_left_alone(rule):
    assert takes_over(rule, record(speed=2.0), steps=100) is None
    # a wheel over the edge is no hazard: the centre stays on the path, the car runs parallel to it
    assert takes_over(rule, record(speed=2.0, d=0.95), steps=100) is None
    # creeping along a hedge 15 cm away (furtive mode) is what the mode asks for
    assert takes_over(rule, record(speed=0.9, d=0.75, border_left=0.15), (0.5, 0.55), (0.5, 0.55), 100) is None


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("fields", [
    {"d": 1.05, "speed": 1.0},                                          # the centre is beyond the edge
    {"d": 0.7, "heading": 0.3, "speed": 2.0},                           # it will be within 0.6 s
    {"d": -0.5, "speed": 4.0, "curvature_ahead": 0.3},                  # straight on into a left bend: out right
    {"heading": 1.3, "speed": 0.5},                                     # turned away from the path
])
def test_leaving_the_path(rule, fields):
    assert takes_over(rule, record(**fields), (0.5, 0.72)) == LEAVING


def test_leaving_is_foreseen_from_the_drivers_command_not_the_present_state_alone():
    into_bend = record(d=-0.5, speed=4.0, curvature_ahead=0.3, steer=0.5)
    assert foresee(into_bend, (0.5, 0.72)) == LEAVING                  # holding straight: off on the outside
    assert foresee(into_bend, (0.25, 0.72)) is None                    # steering into the bend: fine


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("speed, motor", [(3.0, 0.67), (1.0, 0.56)])
def test_an_obstacle_in_the_way_is_taken_over_when_the_swerve_needs_the_room_left(rule, speed, motor):
    """Heading straight at an obstacle, the expert takes over once the way left to it is no more than its swerve
    needs (from the car's offset, heading and speed) plus swerve_margin: not before, and not too late."""
    margin = CorrectionRule().p.swerve_margin
    base = {"speed": speed, "obstacle_d": 0.1, "obstacle_width": 0.3}
    need = swerve_needed(record(obstacle_gap=5.0, **base), CorrectionRule().p.clearance) + margin
    assert 0.8 < need < 2.5
    assert takes_over(rule, record(obstacle_gap=need - 0.05, **base), (0.5, motor)) == f"{COLLISION}: an obstacle"
    assert takes_over(rule, record(obstacle_gap=need + 0.2, **base), (0.5, motor)) is None
    assert takes_over(rule, record(obstacle_gap=0.3, **base), (0.5, motor)) == f"{COLLISION}: an obstacle"


def test_a_lead_car_alongside_is_a_hazard_and_one_left_behind_is_not():
    beside = {"speed": 2.0, "d": 0.3, "heading": -0.15, "lead_d": 0.05, "lead_speed": 1.0}
    assert foresee(record(lead_gap=-0.5, **beside), (0.55, 0.61)) == f"{COLLISION}: the lead car"   # drifting into it
    assert foresee(record(lead_gap=-3.0, **beside), (0.55, 0.61)) is None        # 2.5 m behind: the car's past


def test_a_car_clear_of_an_obstacle_but_closing_on_it_is_taken_over_before_it_touches():
    """The MultiNet study's contact while correcting: the car cleared the obstacle by a millimetre and the rule
    judged the swerve from the present state (none needed), so it waited until the expert could no longer turn
    away. Closing on it, the swerve needs the way the car takes to turn parallel."""
    assert foresee(record(**SQUEEZED), (0.52, 0.69)) == f"{COLLISION}: an obstacle"
    parallel = record(**{**SQUEEZED, "d": 1.2, "heading": 0.0, "steer": 0.466})      # 1.5 cm clear, following
    assert foresee(parallel, (0.466, 0.69)) is None                                   # the bend: no hazard


@pytest.mark.parametrize("rule", RULES)
def test_an_obstacle_the_driver_clears_is_no_hazard(rule):
    # beside the car's lane, or the driver already turning away from it, or the car alongside and clear of it
    assert takes_over(rule, record(speed=3.0, obstacle_gap=1.5, obstacle_d=0.7, obstacle_width=0.3), (0.5, 0.67)) \
        is None
    ahead = {"speed": 2.0, "obstacle_gap": 0.6, "obstacle_d": 0.25, "obstacle_width": 0.3}
    assert foresee(record(**ahead), (0.5, 0.61)) == f"{COLLISION}: an obstacle"
    assert foresee(record(heading=-0.3, **ahead), (0.7, 0.61)) is None
    assert foresee(record(speed=2.0, obstacle_gap=-0.5, obstacle_d=0.5, obstacle_width=0.3), (0.5, 0.61)) is None


@pytest.mark.parametrize("rule", RULES)
def test_a_border_or_the_lead_car_about_to_be_touched(rule):
    # 15 cm from the hedge, heading 0.2 rad towards it at 1 m/s: touching within a second
    assert takes_over(rule, record(speed=1.0, d=0.75, heading=0.2, border_left=0.15), (0.5, 0.56)) == \
        f"{COLLISION}: a border"
    assert takes_over(rule, record(speed=1.0, d=-0.75, heading=-0.2, border_right=0.15), (0.5, 0.56)) == \
        f"{COLLISION}: a border"
    assert takes_over(rule, record(speed=1.0, d=0.75, heading=-0.2, border_left=0.15), (0.5, 0.56)) is None  # away
    assert takes_over(rule, record(speed=2.0, lead_gap=0.8, lead_speed=0.0), (0.5, 0.61)) == \
        f"{COLLISION}: the lead car"
    assert takes_over(rule, record(speed=2.0, lead_gap=1.2, lead_speed=2.0), (0.5, 0.61)) is None   # keeping pace


@pytest.mark.parametrize("rule", RULES)
def test_a_car_that_stalls_where_the_expert_would_drive_is_taken_over(rule):
    stopped, driver, expert = record(speed=0.05), (0.5, 0.52), (0.5, 0.66)   # motor 0.52 vs 0.66: within motor_dev
    steps = round(CorrectionRule().p.stall_time / CorrectionRule().dt)
    assert takes_over(rule, stopped, driver, expert, steps - 1) is None
    assert takes_over(rule, stopped, driver, expert, steps) == STALLED
    # behind a stopped lead car the expert stops too: standing still is right
    assert takes_over(rule, stopped, (0.5, 0.5), (0.5, 0.5), 3 * steps) is None


def test_only_the_strict_rule_takes_over_for_deviating_from_the_expert():
    wrong = ((0.85, 0.53), (0.5, 0.53))       # steering 0.35 off the expert's, slowly, on a wide, empty path
    calm = record(speed=0.5, path_width=3.0)
    assert foresee(calm, wrong[0]) is None    # nothing unsafe within the next second
    assert takes_over("safety", calm, *wrong, steps=100) is None
    strict = CorrectionRule(rule="strict")
    for _ in range(strict.p.deviation_steps - 1):
        assert not strict.update(calm, *wrong)
    assert not strict.update(calm, wrong[1], wrong[1])   # a moment's disagreement is forgiven
    for _ in range(strict.p.deviation_steps - 1):
        assert not strict.update(calm, *wrong)
    assert strict.update(calm, *wrong) and strict.reason == DEVIATING


def test_a_rule_that_does_not_exist_is_refused():
    with pytest.raises(ValueError, match="unknown correction rule 'lenient'"):
        check_rule("lenient")
    with pytest.raises(ValueError):
        CorrectionRule(rule="lenient")


@pytest.mark.parametrize("rule", RULES)
def test_hand_back_after_a_recovery(rule):
    r = CorrectionRule(rule=rule)
    assert r.update(record(d=1.05, speed=1.0), *SAME)
    steps = 0
    while r.update(record(d=0.0, speed=2.0), *SAME):
        steps += 1
        assert steps < 200
    drove = (steps + 1) * r.dt                                        # the take-over step and those after it
    assert drove == pytest.approx(max(r.p.min_correction, r.p.recovery))
    assert r.update(record(d=1.05, speed=1.0), *SAME)                # and takes over again
    for _ in range(20):                                              # not recovered while the body is off the path
        assert r.update(record(d=0.95, speed=2.0, heading=0.05), *SAME)
    for _ in range(20):                                              # nor while it points away from the path
        assert r.update(record(d=0.0, speed=2.0, heading=0.4), *SAME)
    for _ in range(int(r.p.recovery / r.dt) - 1):                    # calm for a second, less one step
        assert r.update(record(d=0.0, speed=2.0), *SAME)
    assert not r.update(record(d=0.0, speed=2.0), *SAME)


def test_take_overs_and_their_steps_are_counted_by_clause():
    r = CorrectionRule()
    for rec, n in ((record(d=1.05, speed=1.0), 1), (record(speed=2.0), 40),
                   (record(speed=3.0, obstacle_gap=0.5, obstacle_width=0.3), 1), (record(speed=2.0), 40)):
        for _ in range(n):
            r.update(rec, *SAME)
    report = r.tally.report(r.dt)
    assert set(report) == {LEAVING, COLLISION}
    assert report[LEAVING]["take_overs"] == 1 and report[COLLISION]["take_overs"] == 1
    assert report[LEAVING]["seconds"] == pytest.approx(30 * r.dt)    # handed back after a second
    assert report[COLLISION]["seconds"] == pytest.approx(30 * r.dt)


def drive(driver, operation: str, path="park", seed: int = 2, mode="direct", seconds: float = 90.0,
          rule: str = "safety", obstacles: float = 4.0):
    w = SidewalkWorld(SidewalkConfig(path=path, seed=seed, mode=mode, obstacles=obstacles, render=False))
    sup, m = Supervisor(w, operation, rule), SidewalkMetrics(w.dt)
    obs = w.observe(False)
    for _ in range(int(seconds / w.dt)):
        command = driver.action(obs.record) if isinstance(driver, SidewalkExpert) else driver.act(obs.record)
        applied, name = sup(obs, np.array(command))
        obs = w.step(applied, False)
        m.update(obs.record)
        assert obs.truth["operation"] == ("autonomous", "correctional").index(name) + 1
        if obs.end is not None:
            break
    return m, obs, sup


@pytest.mark.parametrize("rule", RULES)
def test_the_expert_keeps_the_poor_driver_safe(rule):
    m, obs, sup = drive(PoorDriver(seed=4), "correctional", rule=rule)
    rep = m.report()
    assert obs.end is None and rep["collisions"] == 0 and rep["off_path_time_s"] == 0.0
    assert rep["corrections"] >= 3 and 30.0 < rep["autonomy_percent"] < 95.0
    tally = sup.rule.tally.report(m.dt)
    assert sum(v["take_overs"] for v in tally.values()) == rep["corrections"]
    assert sum(v["seconds"] for v in tally.values()) == pytest.approx(rep["correction_time_s"], abs=1e-6)
    alone, last, _ = drive(PoorDriver(seed=4), "autonomous")
    alone = alone.report()
    assert last.end is not None or alone["collisions"] > 0 or alone["off_path_time_s"] > 0   # without it: trouble


@pytest.mark.parametrize("mode", ["direct", "follow", "furtive"])
def test_the_safety_rule_leaves_the_expert_alone(mode):
    """The expert is driving safely by construction: the rule that measures safety must never take it over (it did,
    before foresight held a driver's command for a reaction time only and judged obstacles by the swerve left)."""
    m, _, _ = drive(SidewalkExpert(), "correctional", "procedural:913", 3, mode, 60.0, obstacles=6.0)
    assert m.correction_steps == 0 and m.collisions == 0


@pytest.mark.parametrize("path, seed, mode, params, seconds", [
    ("procedural:913", 2, "direct", PoorParams(), 42.0),     # the expert, taking over near an obstacle, cut across it
    ("procedural:907", 2, "furtive", WILD, 48.0),             # a car turned round: the expert steered into the hedge
    ("procedural:913", 1, "furtive", WILD, 52.0),             # taken over 1.2 m before an obstacle at 1.4 m/s: too late
])
def test_no_collision_while_the_expert_holds_the_wheel(path, seed, mode, params, seconds):
    """The runs in which the expert collided under the first rule (which looked at the present state only) and the
    first expert (which could choose to cross in front of an obstacle it was about to reach)."""
    m, _, _ = drive(PoorDriver(seed=seed, params=params), "correctional", path, seed, mode, seconds, obstacles=6.0)
    assert m.collisions_correcting == 0 and m.correction_steps > 0


@pytest.mark.slow
@pytest.mark.parametrize("rule", RULES)
def test_no_collision_while_correcting_poor_and_wild_drivers(rule):
    for params in (PoorParams(), WILD):
        for path in ("procedural:907", "procedural:913", "forest", "sidewalk"):
            for mode in ("direct", "furtive"):
                for seed in (1, 2, 3):
                    m, _, _ = drive(PoorDriver(seed=seed, params=params), "correctional", path, seed, mode, 60.0,
                                    rule, obstacles=6.0)
                    assert m.collisions_correcting == 0, (params, path, mode, seed)


def test_corrected_steps_are_flagged_in_the_record():
    w = SidewalkWorld(SidewalkConfig(path="park", seed=2, render=False))
    sup = Supervisor(w, "correctional")
    obs = w.observe(False)
    far_off = np.array([0.38, 0.65])                                 # a little left, fast: over the edge in time
    flags = []
    for _ in range(60):
        applied, name = sup(obs, far_off)
        obs = w.step(applied, False)
        flags.append((obs.truth["correcting"], obs.truth["operation"], name))
    assert flags[0] == (False, 1, "autonomous")
    assert any(f == (True, 2, "correctional") for f in flags)
    expert = SidewalkExpert()
    assert sup.expert.action(obs.record) == pytest.approx(expert.action(obs.record))
