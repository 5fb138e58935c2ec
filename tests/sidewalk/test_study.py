"""The MultiNet study (drivestudio/worlds/sidewalk/study.py): the correction rounds' merge (a network's recorded run
adds only the expert's corrections to the training data, and the validation set stays the original data's), the
data plan, bad input, and the whole study in its --quick form."""
import json
import subprocess
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest
import torch

from core import worlds
from drivestudio.errors import RunError
from drivestudio.worlds.sidewalk.autonomy import Drive, drive_round, retrain
from drivestudio.worlds.sidewalk.study import QUICK, Job, Study, StudyConfig, run_jobs
from perception.checkpoint import load_checkpoint, save_checkpoint
from perception.models import Regressor, make_spec
from perception.moments import Moments
from perception.multinet import resolve
from perception.shards import Dataset
from perception.training import TrainConfig

REPO = Path(__file__).resolve().parents[2]
SIDEWALK = worlds.get("sidewalk")


@pytest.fixture(scope="module")
def merged(tmp_path_factory):
    """A small expert data set, an untrained MultiNet and one correction run of it (4 s, the expert correcting)."""
    root = tmp_path_factory.mktemp("rounds")
    data = root / "data"
    from drivestudio.cli import main
    assert main(["generate", "--world", "sidewalk", "--out", str(data), "--frames", "240", "--episode-frames", "40",
                 "--paths", "park", "--workers", "1"]) == 0
    torch.manual_seed(0)
    model = Regressor(make_spec("z2color", SIDEWALK, modal=True, modes_trained=list(SIDEWALK.modes)))
    save_checkpoint(root / "m.pt", {"spec": model.spec, "state_dict": model.state_dict(), "train": {},
                                    "data": {"roots": [str(data)]}})
    result = drive_round(Drive(str(root / "m.pt"), "direct", 4.0, video=False), root / "round", 0, log=lambda *a: None)
    return data, Path(result.dataset), root / "m.pt", result


def test_a_round_adds_only_the_experts_corrections(merged):
    data, corrections, _, result = merged
    labels = Dataset(corrections).labels(columns=("operation", "correcting"))
    assert result.corrections >= 1 and labels["correcting"].any() and (labels["operation"][1:] == 1).any()
    alone = Moments([data], (94, 168), log=lambda *a: None)
    both = Moments([data, corrections], (94, 168), log=lambda *a: None)
    added = np.flatnonzero([e[0] == str(corrections) for e in both.episodes])
    expert = labels["operation"] != 1
    expected = [t for t in range(1, len(expert) - 10) if expert[t + 1:t + 11].all()]
    assert len(both) == len(alone) + len(added) and len(added) == len(expected) > 0
    steps = both.index[added] - both.offsets[-2]                     # the corrections are the last shard
    assert steps.tolist() == expected                                 # exactly the moments the expert drove ahead
    assert (both.modes[added] == 0).all()                             # driven in direct mode


def test_the_validation_set_stays_the_original_datas(merged):
    data, corrections, _, _ = merged
    alone = Moments([data], (94, 168), log=lambda *a: None)
    both = Moments([data, corrections], (94, 168), log=lambda *a: None)
    train_a, held_a = alone.split([0, 1, 2], seed=0)
    train_b, held_b = both.split([0, 1, 2], seed=0)
    np.testing.assert_array_equal(held_a, held_b)                     # the same held-out moments, in the same order
    added = {i for i, e in enumerate(both.episodes) if e[0] == str(corrections)}
    assert added <= set(train_b[0].tolist())                          # every correction moment trains


def test_retraining_merges_the_corrections(merged, tmp_path):
    data, corrections, start, _ = merged
    out = retrain(str(start), [str(data), str(corrections)], tmp_path / "round1.pt", epochs=1, seed=0, device="cpu",
                  log=lambda *a: None)
    ckpt = load_checkpoint(out)
    assert [Path(r).name for r in ckpt["data"]["roots"]] == ["data", "corrections-0"]
    assert ckpt["train"]["config"]["init"] == str(start) and ckpt["spec"]["options"]["modal"]
    first = load_checkpoint(start)["state_dict"]
    assert any(not torch.equal(first[k], v) for k, v in ckpt["state_dict"].items())   # it learned from them


def test_a_capped_epoch_draws_at_most_mode_moments_of_each_mode(merged):
    """`train --set mode_moments=N` (a study's round_moments): an epoch is N moments per mode trained, however large
    the merged data has grown; MultiNet trains three modes, an MTL net one."""
    data, corrections, _, _ = merged
    roots = f"{data},{corrections}"
    full = resolve(TrainConfig(data=roots, model="z2color", batch_size=30), log=lambda *a: None)
    capped = resolve(TrainConfig(data=roots, model="z2color", batch_size=30, mode_moments=30), log=lambda *a: None)
    mtl = resolve(TrainConfig(data=roots, model="z2color", batch_size=30, mode_moments=30, mtl="direct"),
                  log=lambda *a: None)
    assert full.steps == sum(len(v) for v in full.train_ids.values()) // 30 > 3
    assert capped.steps == 3 and mtl.steps == 1                        # 30 per mode, batches of 30
    roomy = resolve(TrainConfig(data=roots, model="z2color", batch_size=30, mode_moments=10**6), log=lambda *a: None)
    assert roomy.steps == full.steps                                  # a cap above the data is one whole pass


# a stand-in verb for the scheduler: records its start, fails (3) if a job it needs has not ended, then sleeps, or
# (a name for seconds) runs until that job has started, 30 s at most
STAND_IN = """import pathlib, sys, time
name, seconds, needs, d = sys.argv[1], sys.argv[2], sys.argv[3], pathlib.Path(sys.argv[4])
(d / (name + ".start")).write_text(repr(time.time()))
if needs != "-" and not (d / (needs + ".end")).exists():
    sys.exit(3)
t0 = time.time()
if seconds[0].isalpha():
    while not (d / (seconds + ".start")).exists() and time.time() - t0 < 30:
        time.sleep(0.02)
else:
    time.sleep(float(seconds))
(d / (name + ".end")).write_text(repr(time.time()))
"""


def _stamp(d: Path, name: str) -> float:
    return float((d / name).read_text())


def test_a_free_slot_takes_the_first_job_whose_jobs_before_it_are_done(tmp_path):
    # a runs until c has started (beside it, not behind b)
    jobs = [Job("a", ["a", "c", "-", tmp_path]), Job("b", ["b", 0.1, "a", tmp_path], after=("a",)),
            Job("c", ["c", 0.1, "-", tmp_path]), Job("d", ["d", 0.1, "-", tmp_path], after=("done-before",))]
    run_jobs(jobs, 2, tmp_path / "logs", command=(sys.executable, "-c", STAND_IN))
    assert _stamp(tmp_path, "c.start") < _stamp(tmp_path, "a.end")     # c did not wait behind b
    assert _stamp(tmp_path, "b.start") >= _stamp(tmp_path, "a.end")    # b waited for a
    assert (tmp_path / "d.end").exists()                                # a job not in the run finished before it


def test_a_failed_job_ends_the_run_and_what_waits_for_it_never_starts(tmp_path):
    jobs = [Job("a", ["a", 0.1, "missing", tmp_path]), Job("b", ["b", 0.1, "-", tmp_path], after=("a",))]
    with pytest.raises(RunError, match="a failed"):
        run_jobs(jobs, 2, tmp_path / "logs", command=(sys.executable, "-c", STAND_IN))
    assert not (tmp_path / "b.start").exists()


def test_each_networks_rounds_wait_for_its_own_previous_round_only(tmp_path):
    study = Study(StudyConfig(out=str(tmp_path), rounds=2))
    final, jobs = study.correction_rounds(("multinet", "mtl-direct", "mtl-furtive"))
    after = {j.name: j.after for j in jobs}
    assert after["round1-multinet-direct"] == () and after["round1-mtl-direct-direct"] == ()
    assert after["round1-retrain-multinet"] == ("round1-multinet-direct", "round1-multinet-follow",
                                                "round1-multinet-furtive")
    assert after["round2-multinet-furtive"] == ("round1-retrain-multinet",)
    assert after["round2-retrain-mtl-direct"] == ("round1-retrain-mtl-direct", "round2-mtl-direct-direct")
    assert final["multinet"] == str(tmp_path / "models" / "multinet-round2.pt")
    for _, mode, title, _, job in study.autonomy_plan("autonomy", final, ("safety",), 1, 2):
        assert job.after == (f"round2-retrain-{'multinet' if title == 'MultiNet' else 'mtl-' + mode}",)
    assert {job.after for *_, job in study.autonomy_plan("baseline", final, ("safety",), 1, 0)} == {()}


def test_only_the_correction_rounds_record_their_steps(tmp_path):
    """The rounds' recordings are what their retrainings merge; the measuring runs' would be read by nothing."""
    study = Study(StudyConfig(out=str(tmp_path), rounds=1))
    final, jobs = study.correction_rounds(("multinet", "mtl-direct", "mtl-furtive"))
    drives = [j for j in jobs if j.argv[0] == "autonomy"]
    assert drives and all(_set(j.argv, "record") is None for j in drives)       # the verb's default: recorded
    runs = [job for *_, job in study.autonomy_plan("autonomy", final, ("safety",), 1, 1)]
    assert runs and all(_set(j.argv, "record") == "false" for j in runs)


def test_the_studys_data_and_draws_reach_every_verb(tmp_path):
    """perturbed goes to generate, steer_share to the first trainings and every round's fine-tuning."""
    calls: list = []
    study = Study(StudyConfig(out=str(tmp_path), rounds=1, perturbed=0.5, steer_share=0.5))
    study.verb = lambda *argv: calls.append([str(a) for a in argv])   # the verb's argv, not run
    study.generate()
    assert calls[0][0] == "generate" and calls[0][calls[0].index("--perturbed") + 1] == "0.5"
    first = []
    study.jobs = lambda stage, jobs: first.extend(jobs)   # the trainings' plan, not run
    study.train()
    _, rounds = study.correction_rounds(("multinet",))
    trainings = first + [j for j in rounds if j.argv[0] == "train"]
    assert len(trainings) == 5
    for job in trainings:
        assert "steer_share=0.5" in job.argv and job.argv[job.argv.index("steer_share=0.5") - 1] == "--set"
    assert Study(StudyConfig(out=str(tmp_path))).draws() == []


def _set(argv, name: str) -> str | None:
    """The value of `--set NAME=VALUE` in an argv (None: not given)."""
    argv = [str(a) for a in argv]
    values = [a.split("=", 1)[1] for i, a in enumerate(argv[1:]) if argv[i] == "--set" and a.startswith(f"{name}=")]
    return values[-1] if values else None


def test_the_studys_conditions_reach_its_data_rounds_and_runs_and_the_new_ones_a_stage_of_their_own(tmp_path):
    """condition goes to generate, every round's drive and every final run; each new condition to the final runs
    of the study's rule again, in new-conditions/NAME; the seeded look adds nothing to any verb."""
    study = Study(StudyConfig(out=str(tmp_path), rounds=1, runs=1, condition="clear,night",
                              new_conditions="fog,low_sun"))
    calls: list = []
    study.verb = lambda *argv: calls.append(argv)   # the verb's argv, not run
    study.generate()
    assert calls[0][0] == "generate" and _set(calls[0], "condition") == "clear,night"
    final, rounds = study.correction_rounds(("multinet", "mtl-direct", "mtl-furtive"))
    drives = [j for j in rounds if j.argv[0] == "autonomy"]
    runs = [j for *_, j in study.autonomy_plan("autonomy", final, study.cfg.rules, 1, 1)]
    assert len(drives) == 5 and {_set(j.argv, "condition") for j in drives + runs} == {"clear,night"}
    new = study.new_conditions_plan(final)
    assert list(new) == ["fog", "low_sun"]
    for name, plan in new.items():
        assert {rule for rule, *_ in plan} == {"safety"} and len(plan) == len(runs) // 2   # the study's rule only
        for *_, where, job in plan:
            assert _set(job.argv, "condition") == name
            assert where.relative_to(tmp_path).parts[:2] == ("new-conditions", name)
    (tmp_path / "s").mkdir()
    seeded = Study(StudyConfig(out=str(tmp_path / "s"), rounds=1))
    seeded.verb = lambda *argv: calls.append(argv)
    seeded.generate()
    _, plain = seeded.correction_rounds(("multinet",))
    assert {_set(argv, "condition") for argv in [calls[-1]] + [j.argv for j in plain]} == {None}
    assert seeded.new_conditions_plan(final) == {}


def _fake_run(where: Path, autonomy: float, condition: str) -> None:
    where.mkdir(parents=True)
    (where / "autonomy.json").write_text(json.dumps({"rounds": [{
        "autonomy_percent": autonomy, "corrections": 1, "collisions": 0, "distance_m": 10.0, "elapsed_s": 2.0,
        "clauses": {}, "condition": condition}]}))


def test_the_report_sets_multinet_against_mtl_under_new_conditions_beside_the_training_ones(tmp_path):
    """From autonomy.json results (made up here): the new conditions' runs together and each on its own, the change
    from the training conditions, and the verdict per mode."""
    from drivestudio.worlds.sidewalk.study_report import conditions_summary, conditions_table
    study = Study(StudyConfig(out=str(tmp_path), rounds=1, runs=2, condition="clear,night",
                              new_conditions="fog,low_sun"))
    final = {n: f"{n}-round1.pt" for n in ("multinet", "mtl-direct", "mtl-furtive")}
    made = {("MultiNet", "direct"): 90.0, ("MTL", "direct"): 80.0, ("MultiNet", "furtive"): 70.0,
            ("MTL", "furtive"): 75.0}
    training_plan = study.autonomy_plan("autonomy", final, ("safety",), 2, 1)
    for _, mode, title, where, _ in training_plan:
        _fake_run(where, made[title, mode] + 10.0, "clear" if where.name.endswith("100") else "night")
    for name, plan in study.new_conditions_plan(final).items():
        for _, mode, title, where, _ in plan:
            _fake_run(where, made[title, mode] - (5.0 if name == "fog" else 0.0), name)
    training = study.autonomy_results(training_plan)["safety"]
    held = {n: study.autonomy_results(p)["safety"] for n, p in study.new_conditions_plan(final).items()}
    summary = conditions_summary(training, held)
    direct, furtive = summary["modes"]["direct"], summary["modes"]["furtive"]
    assert direct["multinet_ahead"] and not furtive["multinet_ahead"]
    multinet = direct["MultiNet"]
    assert multinet["new"]["autonomy_mean"] == 87.5 and multinet["new"]["runs"] == 8     # 2 loops x 2 runs x 2
    assert multinet["training"]["autonomy_mean"] == 100.0 and multinet["change"] == -12.5
    assert multinet["by_condition"]["fog"]["autonomy_mean"] == 85.0 and multinet["drawn"] == "clear 2, night 2"
    table = conditions_table(summary, "clear,night")
    assert "| direct | MultiNet | 100.00 ± 0.00 | clear 2, night 2 | **87.50 ± " in table
    assert table.splitlines()[0].endswith("| fog | low_sun |") and "| -12.50 | 85.00 ± 0.00 | 90.00 ± 0.00 |" in table
    assert "direct yes (87.50 against 77.50); furtive no (67.50 against 72.50)" in table


def test_the_data_plan_holds_the_moments_asked_for():
    c = StudyConfig()
    episodes = c.frames // c.episode_frames
    assert c.frames % c.episode_frames == 0 and episodes % 3 == 0
    assert episodes * (c.episode_frames - 11) >= 30_000 > (episodes - 3) * (c.episode_frames - 11)
    assert c.rules == ("safety", "strict") and StudyConfig(rule="strict").rules == ("strict", "safety")


@pytest.mark.parametrize("argv, says", [
    (["--set", "rounds=0"], "--set rounds must be an integer from 1 to 20"),
    (["--set", "rule=lenient"], "invalid choice: 'lenient'"),
    (["--set", "loops=park"], "park is driven by the study's data or rounds"),
    (["--set", "loops=procedural:3"], "procedural:3 is driven by the study's data"),
    (["--set", "loops=nowhere.json"], "loops: no such file"),
    (["--set", "loops=,"], "loops names no loop"),
    (["--set", "perturbed=1.5"], "--set perturbed"),
    (["--jobs", "0"], "--jobs must be an integer from 1 to 64"),
    (["--set", "condition=clear,night", "--set", "new_conditions=night,fog"], "night is also in condition=clear"),
    (["--set", "new_conditions=low_sun"], "the seeded look of condition=seeded draws low_sun"),   # its evening
    (["--set", "condition=clear", "--set", "new_conditions=fog,fog"], "names fog more than once"),
    (["--set", "new_conditions=seeded"], "new_conditions: invalid choice: 'seeded'"),
])
def test_bad_input_is_one_line_and_status_2(run_cli, argv, says, tmp_path):
    r = run_cli("study", "--out", tmp_path / "s", *argv, cwd=REPO)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and says in r.stderr, r.stderr
    assert not (tmp_path / "s").exists()


def test_a_study_continues_only_with_the_settings_that_made_it(run_cli, tmp_path):
    out = tmp_path / "s"
    out.mkdir()
    made = json.dumps({**asdict(StudyConfig(out=str(out))), "epochs": 12}, indent=1)
    (out / "config.json").write_text(made)
    r = run_cli("study", "--out", out, "--set", "rounds=3", cwd=REPO)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "epochs=12 (asked 5)" in r.stderr and "rounds" not in r.stderr     # more rounds only add
    assert (out / "config.json").read_text() == made and sorted(p.name for p in out.iterdir()) == ["config.json"]


@pytest.mark.parametrize("setting, option, made_as", [
    ("round_moments", ["--set", "round_moments=5000"], "round_moments=0 (asked 5000)"),   # every round drew all
    ("perturbed", ["--set", "perturbed=0.5"], "perturbed=0.0 (asked 0.5)"),               # expert data only
    ("steer_share", ["--set", "steer_share=0.5"], "steer_share=0.0 (asked 0.5)"),         # modes balanced only
    ("condition", ["--set", "condition=clear,fog"], "condition='seeded' (asked 'clear,fog')"),   # the seeded look
])
def test_a_study_made_before_a_setting_existed_continues_as_it_was_made(run_cli, tmp_path, setting, option, made_as):
    """A config.json without a setting was made with the value the setting has for it (MADE_BEFORE): asking for
    another is a different study, refused before any work."""
    out = tmp_path / "s"
    out.mkdir()
    made = json.dumps({k: v for k, v in asdict(StudyConfig(out=str(out))).items() if k != setting})
    (out / "config.json").write_text(made)
    r = run_cli("study", "--out", out, *option, cwd=REPO)
    assert r.returncode == 2 and made_as in r.stderr, r.stderr
    assert (out / "config.json").read_text() == made                  # untouched


@pytest.mark.parametrize("text", ["[1, 2]", "{not json"])
def test_a_study_folder_with_a_broken_config_is_refused(run_cli, tmp_path, text):
    out = tmp_path / "s"
    out.mkdir()
    (out / "config.json").write_text(text)
    r = run_cli("study", "--out", out, cwd=REPO)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "config.json" in r.stderr, r.stderr
    assert (out / "config.json").read_text() == text


@pytest.mark.slow
def test_the_quick_study_runs_end_to_end_and_continues(tmp_path):
    out = tmp_path / "study"
    cmd = [sys.executable, "-m", "drivestudio", "study", "--quick", "--out", str(out)]
    r = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, r.stderr[-3000:]
    study = json.loads((out / "study.json").read_text())
    assert set(study["autonomy"]) == {"safety", "strict"}
    for rule in ("safety", "strict"):
        for mode in ("direct", "furtive"):
            for net in ("MultiNet", "MTL"):
                a = study["autonomy"][rule][mode][net]
                assert a["runs"] == 2 and 0.0 <= a["autonomy_mean"] <= 100.0
                assert a["collisions_while_correcting"] == 0
    rounds = QUICK["rounds"]                         # --quick's rounds, shorter
    assert rounds >= 2 and study["final_networks"]["multinet"].endswith(f"multinet-round{rounds}.pt")
    assert sorted(p.name for p in (out / "rounds").iterdir()) == [f"round{k}" for k in range(1, rounds + 1)]
    assert len(study["validation"]["multinet"]) == 2 and (out / "figure7-all-modes.png").stat().st_size > 10_000
    assert "## Percentage autonomy" in (out / "STUDY.md").read_text()
    again = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600)   # all done: nothing redone
    assert again.returncode == 0 and "$ drivestudio train" not in again.stdout
    assert "$ drivestudio autonomy" not in again.stdout
    more = subprocess.run(cmd + ["--set", f"rounds={rounds + 1}"], cwd=REPO, capture_output=True, text=True,
                          timeout=900)
    assert more.returncode == 0, more.stderr[-3000:]                 # one more round, and the newer nets measured
    final = json.loads((out / "study.json").read_text())["final_networks"]
    assert final["multinet"].endswith(f"multinet-round{rounds + 1}.pt")
    assert "$ drivestudio train" in more.stdout and "--init" in more.stdout
    assert f"/multinet-round{rounds + 1}/" in more.stdout               # autonomy measured anew, not the old results
