"""Scripted scenarios' events do what the file says, measured from the world's state (the cars SUMO drives, step by
step), and the same scenario gives the same trace bit for bit, run after run and over either SUMO transport."""
import json

import numpy as np
import pytest

from sim.highway.scripted import STOP_DECEL, load_scripted
from sim.highway.world import World, WorldConfig

DT = 0.1
COAST = [0.0, 0.0, 0.0]   # the host neither steers nor drives: the actors are what is measured


def scenario(tmp_path, actors, events, lanes=3, seconds=8.0, traffic=0):
    path = tmp_path / "s.json"
    path.write_text(json.dumps({"version": 2, "route": {"track": "oval", "lanes": lanes, "traffic": traffic,
                                                        "seed": 1, "seconds": seconds},
                                "host": {"s": 0, "lane": 1, "speed": 10}, "actors": actors, "events": events}))
    return path


def drive(path, steps=None, transport="auto"):
    """(world time per step, the actors' speed, lane and d per step, the scenario's report)."""
    with World(WorldConfig(scenario=str(path), render=False, sumo=transport)) as w:
        n = len(w.script.actors)
        t, v, lane, d = [], [], [], []
        for _ in range(steps or int(round(w.script.seconds / DT))):
            w.step(COAST)
            c = w.last_cars
            t.append(w.t)
            v.append(c.speed[:n].copy())
            d.append(c.d[:n].copy())
            lane.append([w._traffic.lane_index(i) for i in range(n)])
        return np.array(t), np.array(v), np.array(lane), np.array(d), w.scenario_report()


def test_a_brake_slows_the_actor_at_its_deceleration_to_its_speed_and_holds_it(tmp_path):
    path = scenario(tmp_path, [{"name": "lead", "gap": 80, "speed": 20}],
                    [{"actor": "lead", "when": {"time": 1.0}, "do": "brake", "decel": 6, "speed": 8}])
    t, v, _, _, report = drive(path)
    dv = np.diff(v[:, 0])
    braking = (t[1:] > 1.0 + 1e-6) & (v[1:, 0] > 8 + 1e-6)
    assert np.allclose(v[t <= 1.0 + 1e-6, 0], 20.0)                  # cruising until the trigger
    assert np.allclose(dv[braking], -6 * DT, atol=1e-6)              # 6 m/s^2, step after step
    assert np.allclose(v[t >= 3.0, 0], 8.0)                          # then the speed it was told
    assert [(e["t"], e["do"]) for e in report["events"]] == [(1.0, "brake")]


def test_a_stop_brings_the_actor_to_a_standstill_that_lasts(tmp_path):
    path = scenario(tmp_path, [{"name": "stopper", "lane_offset": -1, "gap": 60, "speed": 12}],
                    [{"actor": "stopper", "when": {"time": 0.5}, "do": "stop"}])
    t, v, _, _, _ = drive(path)
    moving = (t > 0.5 + 1e-6) & (v[:, 0] > 0)
    assert np.allclose(np.diff(v[:, 0])[moving[1:]], -STOP_DECEL * DT, atol=1e-6)
    assert np.all(v[t >= 0.5 + 12 / STOP_DECEL + DT, 0] == 0.0)


def test_slow_changes_the_speed_at_its_rate_either_way(tmp_path):
    path = scenario(tmp_path, [{"name": "a", "lane_offset": 1, "gap": 60, "speed": 10},
                               {"name": "b", "lane_offset": -1, "gap": 90, "speed": 20}],
                    [{"actor": "a", "when": {"time": 0}, "do": "slow", "speed": 13, "rate": 1.0},
                     {"actor": "b", "when": {"time": 0}, "do": "slow", "speed": 17}])
    t, v, _, _, _ = drive(path, steps=60)
    assert np.allclose(v[t <= 3.0 + 1e-6, 0], 10 + t[t <= 3.0 + 1e-6])   # up at 1 m/s^2
    assert np.allclose(v[t >= 3.0, 0], 13.0)
    assert np.allclose(v[t >= 2.0, 1], 17.0) and np.allclose(v[:10, 1], 20 - 1.5 * t[:10])  # down at 1.5 (default)


def test_a_lane_change_moves_the_actor_one_lane_towards_the_host_over_two_seconds(tmp_path):
    path = scenario(tmp_path, [{"name": "cutter", "lane_offset": 1, "gap": 60, "speed": 10}],
                    [{"actor": "cutter", "when": {"time": 1.0}, "do": "change_lane"}])
    t, _, lane, d, report = drive(path, steps=50)
    assert set(lane[t <= 1.0 + 1e-6, 0]) == {0} and set(lane[t >= 2.3, 0]) == {1}   # the host's lane, from the left
    assert np.allclose(d[t <= 1.0 + 1e-6, 0], 4.0) and d[t > 1.05, 0][0] < 4.0      # it moves from the next step
    assert np.all(np.abs(d[t >= 3.0, 0]) < 0.5) and abs(d[-1, 0]) < 0.01             # across in SUMO's 2 s
    assert report["events"][0]["note"] == "from lane 0 to lane 1"


def test_a_lane_change_to_a_side_without_a_lane_does_nothing_and_says_so(tmp_path):
    path = scenario(tmp_path, [{"name": "edge", "lane_offset": 1, "gap": 60, "speed": 10}],
                    [{"actor": "edge", "when": {"time": 0.2}, "do": "change_lane", "towards": "left"}])
    _, _, lane, _, report = drive(path, steps=30)
    assert set(lane[:, 0]) == {0}
    assert report["events"][0]["note"] == "no lane to its left: nothing done"


def test_resume_hands_the_actor_to_sumo_which_drives_it_to_the_speed_it_wants(tmp_path):
    path = scenario(tmp_path, [{"name": "a", "lane_offset": 0, "gap": 80, "speed": 10}],
                    [{"actor": "a", "when": {"time": 0.5}, "do": "resume", "speed": 16}], seconds=12)
    t, v, _, _, _ = drive(path)
    gain = np.diff(v[:, 0])
    assert np.allclose(v[t <= 0.5 + 1e-6, 0], 10.0)
    assert 0 < gain[(t[1:] > 0.6) & (t[1:] < 2)].min() and gain.max() <= 2.6 * DT + 1e-6   # SUMO's own acceleration
    assert v[-1, 0] == pytest.approx(16.0, abs=0.05)


def test_a_gap_trigger_fires_when_the_gap_reaches_its_value_from_either_side(tmp_path):
    # the host at 10 m/s closes on a slower car ahead, and a faster one comes up from behind
    path = scenario(tmp_path, [{"name": "slow", "lane_offset": 1, "gap": 40, "speed": 5},
                               {"name": "fast", "lane_offset": -1, "gap": -30, "speed": 16}],
                    [{"actor": "slow", "when": {"gap": 20}, "do": "stop"},
                     {"actor": "fast", "when": {"gap": 12}, "do": "slow", "speed": 10}])
    with World(WorldConfig(scenario=str(path), render=False)) as w:
        gaps = []
        for _ in range(80):
            gaps.append(w.script.track.gap(w.ego.s, w.last_cars.s[:2]).copy())
            t_before = w.t
            w.step(COAST)
            fired = {e["actor"]: e["t"] for e in w.scenario_report()["events"]}
            for i, name, value in ((0, "slow", 20), (1, "fast", 12)):
                if fired.get(name) == round(t_before, 3) and len(gaps) > 1:
                    crossed = (gaps[-2][i] - value) * (gaps[-1][i] - value) <= 0   # between the last two states
                    assert crossed, (name, gaps[-2][i], gaps[-1][i])
        assert set(fired) == {"slow", "fast"}


def test_the_same_scenario_gives_the_same_trace_bit_for_bit_in_two_runs_and_over_either_transport(tmp_path):
    path = scenario(tmp_path, [{"name": "lead", "gap": 40, "speed": 12},
                               {"name": "side", "lane_offset": 1, "gap": 20, "speed": 11}],
                    [{"actor": "side", "when": {"gap": 24}, "do": "change_lane"},
                     {"actor": "lead", "when": {"time": 2}, "do": "resume"}], seconds=6, traffic=6)
    first = drive(path)[4]
    again = drive(path)[4]
    over_traci = drive(path, transport="traci")[4]
    assert first["steps"] == 60 and len(first["events"]) == 2
    assert first == again == over_traci


def test_a_reset_replays_the_scenario_from_its_start(tmp_path):
    path = scenario(tmp_path, [{"name": "lead", "gap": 40, "speed": 12}],
                    [{"actor": "lead", "when": {"time": 1}, "do": "brake", "decel": 3, "speed": 4}], seconds=3)
    with World(WorldConfig(scenario=str(path), render=False)) as w:
        for _ in range(30):
            w.step(COAST)
        first = w.scenario_report()
        w.reset(seed=99)   # a scenario keeps its own seed
        assert w.seed == load_scripted(path).seed and w.t == 0.0 and w.scenario_report()["events"] == []
        for _ in range(30):
            w.step(COAST)
        assert w.scenario_report() == first
