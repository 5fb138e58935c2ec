"""benchmark --scenarios as docs/scenarios.md and docs/benchmark.md specify it: pass or fail per scenario beside the
driving score (scenarios.csv, a table in leaderboard.md), the same traces over shared memory, a scenario beside every
collision's clip that replays it, and the shipped suite."""
import csv
import json
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from drivestudio.loop import in_process, run_loop
from drivestudio.worlds.highway.benchmark.replay import replay_scenario
from drivestudio.worlds.highway.benchmark.scenarios import SCENARIOS_DIR, load_scenarios
from drivestudio.worlds.highway.drivers import ChenDriver
from sim.highway.scripted import EVENT_FIELDS, load_scripted
from sim.highway.traffic import CarStates
from sim.highway.world import World, WorldConfig
from sim.track import load_track

# the plain oracle runs into a car braking hard 20 m ahead; the extended oracle (L5) stops in time; both let a
# slower car cut in 25 m ahead and keep their distance
BRAKE = {"version": 2, "name": "brake", "route": {"track": "oval", "lanes": 1, "seed": 2, "seconds": 4},
         "host": {"s": 0, "lane": 0, "speed": 20}, "actors": [{"name": "lead", "gap": 20, "speed": 20}],
         "events": [{"actor": "lead", "when": {"time": 0.5}, "do": "brake", "decel": 9}]}
CUT_IN = {"version": 2, "name": "cut-in", "route": {"track": "oval", "lanes": 2, "seed": 3, "seconds": 4},
          "host": {"s": 0, "lane": 1, "speed": 20},
          "actors": [{"name": "cutter", "lane_offset": 1, "gap": 30, "speed": 15}],
          "events": [{"actor": "cutter", "when": {"gap": 25}, "do": "change_lane"}], "pass": {"min_time_gap": 0.3}}


def rows(out):
    with open(out / "scenarios.csv") as f:
        return {(r["model"], r["scenario"]): r for r in csv.DictReader(f)}


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("scenarios")
    for obj in (BRAKE, CUT_IN):
        (d / f"{obj['name']}.json").write_text(json.dumps(obj))
    return d


@pytest.fixture(scope="module")
def benchmark(folder, tmp_path_factory):
    """Both oracles on the two scenarios, in process and over shared memory."""
    outs = {}
    for transport in ("in-process", "shm"):
        out = tmp_path_factory.mktemp(transport) / "bench"
        argv = ["benchmark", "--model", "oracle-extended", "--scenarios", str(folder), "--workers", "2", "--clips",
                "1", "--out", str(out), *(["--shm"] if transport == "shm" else [])]
        run = subprocess.run([sys.executable, "-m", "drivestudio", *argv], capture_output=True, text=True, timeout=600)
        assert run.returncode == 0, run.stderr
        outs[transport] = out
    return outs


@pytest.mark.long   # both oracles over two scenarios, in process and over shared memory: 12 s
def test_each_scenario_passes_or_fails_per_model_in_scenarios_csv_and_the_leaderboard(benchmark):
    out = benchmark["in-process"]
    got = rows(out)
    assert {k: v["passed"] for k, v in got.items()} == {
        ("oracle", "brake"): "False", ("oracle", "cut-in"): "True",
        ("oracle-extended", "brake"): "True", ("oracle-extended", "cut-in"): "True"}
    assert got[("oracle", "brake")]["failed"].startswith("collision at")
    assert float(got[("oracle-extended", "cut-in")]["min_time_gap_s"]) >= 0.3
    assert got[("oracle", "cut-in")]["events_fired"] == "1"
    text = (out / "leaderboard.md").read_text()
    table = text[text.index("## Scenarios"):text.index("## Per route")]
    assert "| scenario | oracle | oracle-extended |" in table
    assert "| brake | FAIL: collision at" in table and "| **passed** | **1 of 2** | **2 of 2** |" in table
    board = json.loads((out / "leaderboard.json").read_text())
    assert board["models"][0]["overall"]["driving_score"] < board["models"][1]["overall"]["driving_score"]


@pytest.mark.long   # both oracles over two scenarios, in process and over shared memory: 12 s
def test_over_shared_memory_every_trace_is_bit_identical(benchmark):
    here, there = rows(benchmark["in-process"]), rows(benchmark["shm"])
    assert here.keys() == there.keys()
    for key in here:
        assert here[key]["trace_sha256"] == there[key]["trace_sha256"], key
        assert here[key]["steps"] == there[key]["steps"] == "40"


@pytest.mark.long   # both oracles over two scenarios, in process and over shared memory: 12 s
def test_a_collision_clip_gets_a_scenario_beside_it_that_replays_the_collision(benchmark):
    out = benchmark["in-process"]
    board = json.loads((out / "leaderboard.json").read_text())
    clip = next(c for r in board["models"][0]["routes"] for c in r["clips"] if c["event"] == "collision")
    path = out / "clips" / "oracle" / clip["scenario"]
    assert (out / clip["file"]).is_file() and path.is_file()
    replay = load_scripted(path)
    assert replay.actors[0].blind and replay.traffic == 0 and replay.criteria.no_collision
    with World(WorldConfig(scenario=str(path), render=False)) as world:
        run_loop(world, in_process(ChenDriver(None)), replay.seconds, render=False)
        report = world.scenario_report()
    start = clip["t"] - (replay.seconds - 2.0)                   # the replay begins this long before the collision
    assert not report["passed"] and report["collision_t"] + start == pytest.approx(clip["t"], abs=0.3)


def test_the_shipped_suite_has_every_event_kind_on_one_to_four_lanes():
    suite = load_scenarios(SCENARIOS_DIR)
    scenarios = [load_scripted(r.scenario) for r in suite.routes]
    assert len(scenarios) >= 12 and {s.lanes for s in scenarios} == {1, 2, 3, 4}
    assert {e.do for s in scenarios for e in s.events} == set(EVENT_FIELDS)
    assert any(e.gap is not None for s in scenarios for e in s.events)
    assert any(len(s.events) > 1 for s in scenarios)   # chains


def test_a_replay_keeps_its_whole_window_when_sumo_inserts_a_car_late():
    """A car SUMO inserts during the window is left out; the cars there throughout keep their identity (not their
    row), so the replay starts as early as the clip allows."""
    track = load_track("oval", lanes=2)
    steps = []
    for k in range(40):
        ids = np.array([0, 2]) if k < 20 else np.array([0, 1, 2])   # car 1 inserted at 2 s, before the others' rows
        s = {0: 30.0 + 1.5 * k * 0.1, 1: 300.0, 2: -20.0 + 2.0 * k * 0.1}
        n = len(ids)
        cars = CarStates(np.zeros(n), np.zeros(n), np.zeros(n), np.array([s[i] for i in ids]),
                         np.array([-2.0 if i == 0 else 2.0 for i in ids]), np.full(n, 4.6), np.full(n, 1.8),
                         np.zeros(n, int), np.zeros(n, int), np.array([15.0 if i == 0 else 20.0 for i in ids]), ids)
        truth = SimpleNamespace(ego=np.array([0, 0, 0, 1.8 * k * 0.1, -2.0]), speed=18.0,
                                indicators=np.zeros(14))
        steps.append(SimpleNamespace(obs=SimpleNamespace(t=10.0 + k * 0.1, truth=truth), cars=cars))
    route = SimpleNamespace(track="oval", track_ref="oval", seed=1)
    obj = replay_scenario(steps, track, route, 13.9, "late", "a test")
    assert obj["route"]["seconds"] == pytest.approx(5.9) and obj["host"]["lane"] == 1
    assert [(a["name"], a["gap"], a["lane_offset"]) for a in obj["actors"]] == [("car0", 30.0, 0), ("car2", -20.0, 1)]


PHYSICS_FORBIDS = {"cut-in-10m-2l", "merge-alongside-3l"}   # docs/scenarios.md, "What physics allows"


@pytest.mark.slow
def test_the_extended_oracle_passes_every_scenario_physics_allows_and_the_oracles_fails_have_clips(tmp_path):
    out = tmp_path / "suite"
    run = subprocess.run([sys.executable, "-m", "drivestudio", "benchmark", "--model", "oracle-extended",
                          "--scenarios", str(SCENARIOS_DIR), "--workers", "2", "--out", str(out)],
                         capture_output=True, text=True, timeout=1800)
    assert run.returncode == 0, run.stderr
    got = rows(out)
    failed = {m: {s for (model, s), r in got.items() if model == m and r["passed"] == "False"}
              for m in ("oracle", "oracle-extended")}
    assert failed["oracle-extended"] == PHYSICS_FORBIDS
    assert failed["oracle"] == {r.name for r in load_scenarios(SCENARIOS_DIR).routes} - {
        "cut-in-20m-2l", "merge-half-ahead-2l", "van-slows-boxed-in-4l"}
    board = json.loads((out / "leaderboard.json").read_text())
    for route in board["models"][0]["routes"]:
        if got[("oracle", route["route"])]["collision_t"]:
            clip = next(c for c in route["clips"] if c["event"] == "collision")
            assert (out / clip["file"]).is_file() and (out / "clips" / "oracle" / clip["scenario"]).is_file()
