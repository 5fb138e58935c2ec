"""Reinforcement learning on the highway (docs/gymnasium.md): the training script's smoke run, and a policy as a
row of the benchmark's leaderboard, a saved Stable-Baselines3 model or a callable."""
import json
import tempfile
from pathlib import Path

import pytest

from drivestudio.errors import UsageError
from drivestudio.worlds.highway.benchmark import ModelSpec, RunOptions
from drivestudio.worlds.highway.benchmark.models import check_model
from drivestudio.worlds.highway.benchmark.route import run_route
from drivestudio.worlds.highway.benchmark.suite import load_suite
from tests.drivestudio import rl_policies
from tests.drivestudio.test_benchmark import ROUTE_B, ds, write_suite
from tests.sim.sumo_processes import sumo_children


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DRIVESTUDIO_CACHE", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """The training script's smoke run: a few hundred steps of PPO, saved."""
    pytest.importorskip("stable_baselines3")
    from drivestudio.worlds.highway.rl_train import train
    model = tmp_path_factory.mktemp("rl") / "ppo.zip"
    temp, tempfile.tempdir = tempfile.tempdir, str(tmp_path_factory.mktemp("tmp"))
    try:
        result = train(minutes=1.0, steps=300, out=model, log=lambda line: None)
    finally:
        temp, tempfile.tempdir = tempfile.tempdir, temp
    assert model.is_file() and result["steps"] >= 300
    assert not list(Path(temp).glob("SB3-*"))   # no log folder of Stable-Baselines3's left in /tmp
    assert sumo_children() == []
    return model


@pytest.mark.long
def test_smoke_training_saves_a_policy_the_benchmark_ranks(tmp_path, trained):
    out = tmp_path / "board"
    short = {**ROUTE_B, "seconds": 4}   # the smoke run: that the row is driven and ranked, not how well
    r = ds("benchmark", "--suite", write_suite(tmp_path / "s.json", [short]), "--model", trained,
           "--workers", "1", "--clips", "0", "--out", out)
    assert r.returncode == 0, r.stderr
    oracle, policy = json.loads((out / "leaderboard.json").read_text())["models"]
    assert oracle["model"] == "oracle" and policy["model"] == "PPO policy (ppo.zip)"
    assert 0.0 <= policy["overall"]["driving_score"] <= 1.0
    assert "PPO policy (ppo.zip)" in r.stdout


@pytest.mark.long
def test_drive_takes_a_saved_policy_over_the_bridge(tmp_path, trained):
    r = ds("drive", "--model", trained, "--track", "oval", "--lanes", "2", "--cars", "4", "--seconds", "2",
           "--out", tmp_path / "run")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "run" / "metrics.json").read_text())["simulated_time_s"] == pytest.approx(2.0)


@pytest.mark.long
def test_over_the_bridge_a_callable_policy_drives_as_the_oracle(tmp_path):
    out = tmp_path / "board"
    r = ds("benchmark", "--suite", write_suite(tmp_path / "s.json", [{**ROUTE_B, "seconds": 5}]), "--shm",
           "--model", "policy:tests.drivestudio.rl_policies:chen", "--workers", "1", "--clips", "0", "--out", out)
    assert r.returncode == 0, r.stderr
    oracle, policy = json.loads((out / "leaderboard.json").read_text())["models"]
    for key in ("driving_score", "collisions", "off_road_events", "distance_km"):
        assert policy["routes"][0][key] == pytest.approx(oracle["routes"][0][key], rel=1e-3), key


def test_a_callable_reading_the_affordances_as_documented_drives_as_the_oracle(tmp_path):
    route = load_suite(str(write_suite(tmp_path / "s.json", [ROUTE_B]))).routes[0]
    opts = RunOptions(clips=0)
    oracle = run_route(route, ModelSpec("oracle", None), opts)
    rl_policies.chen = rl_policies.ChenOnAffordances()   # a fresh controller for this run
    spec = check_model("policy:tests.drivestudio.rl_policies:chen")
    assert spec.policy and spec.label == "tests.drivestudio.rl_policies:chen"
    policy = run_route(route, spec, opts)
    assert policy["end"] == oracle["end"] == "finished"
    for key in ("collisions", "off_road_events", "lane_changes"):
        assert policy["metrics"].get(key) == oracle["metrics"].get(key), key
    assert policy["metrics"]["distance_m"] == pytest.approx(oracle["metrics"]["distance_m"], rel=1e-3)


@pytest.mark.parametrize("model, message", [
    ("missing.zip", "--model missing.zip: no such file"),
    ("policy:no.such.module:fn", "--model policy:no.such.module:fn: cannot import it"),
    ("policy:nonsense", "--model policy:nonsense: a policy callable is policy:MODULE:NAME"),
])
def test_a_policy_that_cannot_drive_is_refused_in_one_line(model, message):
    with pytest.raises(UsageError, match=message.replace(".", r"\.")):
        check_model(model)


def test_a_zip_that_is_no_saved_model_is_refused(tmp_path):
    bad = tmp_path / "weights.zip"
    bad.write_bytes(b"PK\x05\x06" + b"\0" * 18)   # an empty zip
    r = ds("benchmark", "--model", bad, "--out", tmp_path / "o")
    assert r.returncode == 2 and r.stderr.strip().splitlines() == [
        f"drivestudio benchmark: error: --model {bad}: not a saved Stable-Baselines3 model (a zip with its 'data')"]
