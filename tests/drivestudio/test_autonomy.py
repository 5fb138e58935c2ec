"""Percentage autonomy (the MultiNet paper's equation 3) and the DAgger loop: the run's steps are recorded with their
operation mode, the autonomy agrees with them, and `--rounds` merges the corrections and retrains."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from core import worlds
from drivestudio.worlds.sidewalk.autonomy import percentage_autonomy
from perception.checkpoint import save_checkpoint
from perception.models import Regressor, make_spec
from perception.shards import Dataset

REPO = Path(__file__).resolve().parents[2]
SIDEWALK = worlds.get("sidewalk")


def test_autonomy_is_one_minus_the_share_of_correction_time():
    assert percentage_autonomy(0.0, 120.0) == 100.0
    assert percentage_autonomy(30.0, 120.0) == pytest.approx(75.0)
    assert percentage_autonomy(120.0, 120.0) == 0.0
    assert percentage_autonomy(8.78, 120.0) == pytest.approx(92.68, abs=0.01)   # the paper's MultiNet, direct
    with pytest.raises(ValueError):
        percentage_autonomy(1.0, 0.0)


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    """An untrained MultiNet (it drives badly, so the expert has to correct it)."""
    torch.manual_seed(0)
    model = Regressor(make_spec("z2color", SIDEWALK, modal=True))
    path = tmp_path_factory.mktemp("autonomy") / "multinet.pt"
    save_checkpoint(path, {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    return path


def test_a_run_records_its_corrections_and_its_autonomy_agrees(checkpoint, tmp_path, run_cli):
    r = run_cli("autonomy", "--model", checkpoint, "--mode", "direct", "--seconds", "3", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    result = json.loads((tmp_path / "autonomy.json").read_text())["rounds"][0]
    ds = Dataset(tmp_path / "corrections-0")
    labels = ds.labels(columns=("correcting", "operation", "behaviour"))
    steps = len(labels["correcting"])
    assert steps == 90 and result["elapsed_s"] == pytest.approx(steps * SIDEWALK.dt, abs=1e-6)
    # the dataset holds the records the driver saw (steps 0..89), each with the command chosen one step earlier; the
    # run's metrics count the commands of steps 0..89 (records 1..90): the two agree but for the run's last command
    corrected = int(np.sum(labels["correcting"][1:]))
    assert round(result["correction_s"] / SIDEWALK.dt) in (corrected, corrected + 1)
    correction = result["correction_s"]
    assert result["autonomy_percent"] == pytest.approx((1 - correction / (steps * SIDEWALK.dt)) * 100, abs=0.01)
    # the record of a step holds the command chosen on the step before (docs/sidewalk.md): from the second step on,
    # every command is the network's (autonomous) or the expert's correction
    assert set(np.unique(labels["operation"][1:])) <= {1, 2}
    assert np.array_equal(labels["operation"] == 2, labels["correcting"])
    assert (labels["behaviour"] == 0).all()                              # driven in direct mode
    assert (tmp_path / "autonomy-0.mp4").stat().st_size > 10_000 and "| 0 | multinet.pt | safety |" in r.stdout


def test_a_run_not_recorded_writes_no_dataset_and_drives_as_a_recorded_one(checkpoint, tmp_path, run_cli):
    """record=false (the study's measuring runs): the same run, its report the same, no corrections-0 written."""
    for name, record in (("recorded", "true"), ("measured", "false")):
        r = run_cli("autonomy", "--model", checkpoint, "--mode", "direct", "--seconds", "2", "--set", "video=false",
                    "--set", f"record={record}", "--out", tmp_path / name)
        assert r.returncode == 0, r.stderr
    recorded, measured = (json.loads((tmp_path / n / "autonomy.json").read_text())["rounds"][0]
                          for n in ("recorded", "measured"))
    assert recorded["dataset"] == str(tmp_path / "recorded" / "corrections-0") and measured["dataset"] is None
    assert (tmp_path / "recorded" / "corrections-0").is_dir() and not (tmp_path / "measured" / "corrections-0").exists()
    del recorded["dataset"], measured["dataset"], recorded["model"], measured["model"]
    assert recorded == measured and recorded["corrections"] > 0


def test_a_highway_model_is_refused_in_one_line(run_cli, tmp_path):
    from core.worlds.highway import HIGHWAY
    model = Regressor(make_spec("gist", HIGHWAY))
    save_checkpoint(tmp_path / "gist.pt", {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    r = run_cli("autonomy", "--model", tmp_path / "gist.pt", "--out", tmp_path / "a", cwd=REPO)
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert "a model of the highway world, not of the sidewalk world" in r.stderr
    assert not (tmp_path / "a").exists()


@pytest.mark.slow
def test_rounds_merge_the_corrections_and_retrain(tmp_path):
    data = tmp_path / "data"
    subprocess.run([sys.executable, "-m", "drivestudio", "generate", "--world", "sidewalk", "--out", str(data),
                    "--frames", "300", "--episode-frames", "50"], cwd=REPO, check=True, timeout=300)
    subprocess.run([sys.executable, "-m", "drivestudio", "train", "--data", str(data), "--model", "z2color", "--out",
                    str(tmp_path / "m.pt"), "--epochs", "1", "--batch-size", "30", "--device", "cpu"], cwd=REPO,
                   check=True, timeout=600, capture_output=True)
    r = subprocess.run([sys.executable, "-m", "drivestudio", "autonomy", "--model", str(tmp_path / "m.pt"),
                        "--seconds", "3", "--rounds", "2", "--set", "epochs=1", "--set", "video=false", "--out",
                        str(tmp_path / "a")],
                       cwd=REPO, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-2000:]
    rounds = json.loads((tmp_path / "a" / "autonomy.json").read_text())["rounds"]
    assert [x["round"] for x in rounds] == [0, 1] and rounds[1]["model"].endswith("model-round1.pt")
    from perception.checkpoint import load_checkpoint
    retrained = load_checkpoint(tmp_path / "a" / "model-round1.pt")
    assert len(retrained["data"]["roots"]) == 2   # the original data and the first round's corrections


@pytest.mark.parametrize("argv, says", [
    (["--rule", "lenient"], "argument --rule: invalid choice: 'lenient'"),
    (["--rounds", "0"], "--rounds must be an integer from 1 to 20, got 0"),
    (["--set", "obstacles=13"], "--set obstacles must be a number from 0 to 12, got 13.0"),
    (["--set", "video=maybe"], "--set video must be true or false, got 'maybe'"),
    (["--rounds", "2", "--set", "record=false"], "--set record=false leaves a retraining nothing to merge"),
])
def test_a_rule_that_does_not_exist_or_no_rounds_is_refused_in_one_line(checkpoint, run_cli, tmp_path, argv, says):
    r = run_cli("autonomy", "--model", checkpoint, *argv, "--out", tmp_path / "a", cwd=REPO)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and says in r.stderr, r.stderr
    assert not (tmp_path / "a").exists()


def test_a_run_reports_its_take_overs_by_clause(checkpoint, tmp_path, run_cli):
    r = run_cli("autonomy", "--model", checkpoint, "--mode", "furtive", "--rule", "strict", "--seconds", "3",
                "--set", "video=false", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    result = json.loads((tmp_path / "autonomy.json").read_text())["rounds"][0]
    assert result["rule"] == "strict" and result["mode"] == "furtive" and result["corrections"] >= 1
    clauses = result["clauses"]
    assert set(clauses) <= {"leaving the path", "imminent collision", "stalled", "deviating from the expert"}
    assert sum(c["take_overs"] for c in clauses.values()) == result["corrections"]
    assert sum(c["seconds"] for c in clauses.values()) == pytest.approx(result["correction_s"], abs=0.01)
    assert result["collisions_while_correcting"] == 0
    assert "| strict |" in (tmp_path / "autonomy.md").read_text()


def test_a_runs_condition_draws_its_loop_and_its_recording_merges_with_data_of_that_kind(checkpoint, tmp_path,
                                                                                        run_cli):
    """`--set condition=A,B`: the run's seed draws one, the world is drawn in it, every recorded frame names it, and
    the recording declares what `generate --set condition=...` declares (so `train --data DATA,CORRECTIONS` merges
    them)."""
    from core.conditions import pick
    mix, seed = "night,fog", 3
    r = run_cli("autonomy", "--model", checkpoint, "--seconds", "1", "--set", f"condition={mix}", "--set",
                f"seed={seed}", "--set", "video=false", "--out", tmp_path / "a", cwd=REPO)
    assert r.returncode == 0, r.stderr
    drawn = pick(mix, seed)
    assert json.loads((tmp_path / "a" / "autonomy.json").read_text())["rounds"][0]["condition"] == drawn
    recorded = Dataset(tmp_path / "a" / "corrections-0")
    assert set(recorded.labels(columns=("condition",))["condition"]) == {drawn}
    _generate("--world", "sidewalk", "--out", tmp_path / "d", "--frames", "20", "--episode-frames", "20", "--set",
              f"condition={mix}", "--paths", "park")
    assert recorded.declaration.fingerprint() == Dataset(tmp_path / "d").declaration.fingerprint()


@pytest.fixture
def autonomy(run_cli, checkpoint):
    """`drivestudio autonomy --model CHECKPOINT ...` in this process: the refusals below come before any work."""
    return lambda *argv: run_cli("autonomy", "--model", checkpoint, *argv, cwd=REPO)


def _generate(*argv):
    from drivestudio.cli import main
    assert main(["generate", *map(str, argv), "--workers", "1"]) == 0


def test_rounds_without_data_are_refused_before_round_0(autonomy, tmp_path):
    r = autonomy( "--rounds", "2", "--seconds", "3", "--out", tmp_path / "a")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--rounds needs the training data" in r.stderr
    assert not (tmp_path / "a").exists()    # refused before anything was driven


def test_merge_data_of_another_world_or_missing_is_refused_before_round_0(autonomy, tmp_path):
    highway = tmp_path / "hw"
    _generate("--out", highway, "--frames", "20", "--episode-frames", "20")
    r = autonomy("--rounds", "2", "--set", f"data={highway}", "--out", tmp_path / "a")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "dataset of the highway world" in r.stderr
    r = autonomy("--set", f"data={tmp_path / 'gone'}", "--out", tmp_path / "a")
    assert r.returncode == 2 and "no dataset folder" in r.stderr
    assert not (tmp_path / "a").exists()


def test_merge_data_too_small_to_hold_an_episode_out_is_refused_before_round_0(autonomy, tmp_path):
    data = tmp_path / "data"   # 3 episodes, one a mode: none to spare for validation
    _generate("--world", "sidewalk", "--out", data, "--frames", "60", "--episode-frames", "20")
    r = autonomy("--rounds", "2", "--set", f"data={data}", "--out", tmp_path / "a")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "fewer than 2 episodes of mode direct (1)" in r.stderr
    assert not (tmp_path / "a").exists()


def test_a_folder_with_an_earlier_run_is_refused(autonomy, tmp_path):
    """A rerun into a run's folder would take its round models as trained already."""
    (tmp_path / "model-round1.pt").write_bytes(b"an earlier run's model")
    r = autonomy("--seconds", "3", "--out", tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "holds an earlier autonomy run" in r.stderr
    assert (tmp_path / "model-round1.pt").read_bytes() == b"an earlier run's model"    # untouched


@pytest.mark.long
def test_sigterm_ends_the_run_in_order_and_the_report_says_it_is_incomplete(tmp_path):
    """Cut off during the retraining after round 0: exit 128 + 15 with one line; autonomy.json holds round 0 and
    "complete": false; no temporary file is left."""
    import signal
    import time
    data = tmp_path / "data"
    _generate("--world", "sidewalk", "--out", data, "--frames", "120", "--episode-frames", "20")
    # 6 episodes: 2 a mode, one of which the retraining holds out
    torch.manual_seed(0)
    model = Regressor(make_spec("z2color", SIDEWALK, modal=True))
    save_checkpoint(tmp_path / "m.pt", {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    out = tmp_path / "a"
    proc = subprocess.Popen([sys.executable, "-m", "drivestudio", "autonomy", "--model", str(tmp_path / "m.pt"),
                             "--seconds", "2", "--rounds", "3", "--set", "epochs=50", "--set", f"data={data}",
                             "--out", str(out)], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.time()
    while not (out / "autonomy.json").exists() and time.time() - t0 < 200 and proc.poll() is None:
        time.sleep(0.2)
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM and "Traceback" not in err, err[-2000:]
    report = json.loads((out / "autonomy.json").read_text())
    assert report["complete"] is False and [x["round"] for x in report["rounds"]] == [0]
    assert "incomplete" in (out / "autonomy.md").read_text()
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]
