"""Closed-loop data aggregation (drivestudio/worlds/highway/aggregation.py, docs/aggregation.md): a real round
(the model and the expert drive mixed, the visited frames are merged with the expert set, the model is fine-tuned)
and what it promises: exact labels on the visited frames, the expert set's splits kept and the new frames in
training, images copied byte for byte, the mixture's share, the same rounds for the same seed, resuming, and bad
input refused before any work."""
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from core.worlds.highway import INDICATORS
from drivestudio.generate import GenerateConfig, generate
from drivestudio.worlds.highway.aggregation import AggregationConfig, AggregationPlugin, drive_options
from perception.shards import MANIFEST, Dataset, image_column
from perception.train import train
from sim.highway.truth import affordances
from sim.track import load_track
from tests.perception.frames import dataset, tiny_config, workdir

pytestmark = pytest.mark.slow   # closed-loop rounds with real training (about 40 s); run with pytest -m slow


@pytest.fixture(scope="module")
def model():
    out = workdir() / "aggregation-start.pt"
    if not out.exists():
        train(tiny_config("mobilenet", out), log=lambda *a: None)
    return out


@pytest.fixture(scope="module")
def run(model, tmp_path_factory):
    out = tmp_path_factory.mktemp("aggregation") / "run"
    r = ds("aggregate", "--data", dataset(), "--model", model, "--out", out, *SMALL)
    assert r.returncode == 0, r.stderr
    return out


# one round of 60 frames, fine-tuned for 2 iterations, no benchmark
SMALL = ("--rounds", 1, "--set", "frames=60", "--set", "episode_frames=20", "--set", "iterations=2", "--set",
         "batch_size=4", "--suite", "none", "--workers", 1)


def ds(*args, timeout=600):
    return subprocess.run([sys.executable, "-m", "drivestudio", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


def test_a_round_records_merges_and_fine_tunes(run):
    state = json.loads((run / "aggregation.json").read_text())
    (r1,) = state["rounds"]
    assert r1["done"] and r1["frames"] == 60 and r1["beta"] == 0.5
    assert r1["merged_frames"] == Dataset(dataset()).frames() + 60
    assert (run / "round-1" / "model.pt").is_file() and "| 1 | 0.500 | 60 |" in (run / "aggregation.md").read_text()


def test_the_visited_frames_carry_the_exact_labels_of_their_state(run):
    data = Dataset(run / "round-1" / "data")
    for shard in data.shards:
        t = data.reader(shard).labels(list(INDICATORS) + ["track", "lanes", "s", "d", "yaw", "cars"])
        for step in (0, shard.frames - 1):
            row = {n: t.column(n)[step].as_py() for n in t.column_names}
            track = load_track(row["track"], lanes=row["lanes"])
            heading = row["yaw"] - track.pose(row["s"], row["d"])[2]
            cars = np.asarray(row["cars"], dtype=np.float64).reshape(-1, 5)
            exact = affordances(track, row["s"], row["d"], (heading + np.pi) % (2 * np.pi) - np.pi, cars[:, 3],
                                cars[:, 4])
            assert np.allclose([row[n] for n in INDICATORS], exact, atol=2e-3), (shard.file, step)


def test_the_expert_sets_splits_stay_and_the_visited_frames_train(run):
    merged, expert = Dataset(run / "round-1" / "merged"), Dataset(dataset())
    assert [(s.episode, s.split) for s in merged.shards if s.episode < 100_000] == \
        [(s.episode, s.split) for s in expert.shards]
    new = [s for s in merged.shards if s.episode >= 100_000]
    assert len(new) == 3 and all(s.split == "train" for s in new)
    assert len({s.episode for s in merged.shards}) == len(merged.shards)


def test_merged_shards_hold_the_same_images_and_renumbered_episodes(run):
    merged, rounds = Dataset(run / "round-1" / "merged"), Dataset(run / "round-1" / "data")
    src = rounds.shards[0]
    dst = next(s for s in merged.shards if s.episode == 100_000 + src.episode)
    col = image_column("front")
    a = rounds.reader(src).labels([col, "episode"])
    b = merged.reader(dst).labels([col, "episode"])
    assert a.column(col).to_pylist() == b.column(col).to_pylist()
    assert set(b.column("episode").to_pylist()) == {100_000 + src.episode}


def test_the_mixture_applies_the_expert_about_beta_of_the_time(model, tmp_path):
    cfg = AggregationConfig(data=str(dataset()), model=str(model), out=str(tmp_path), beta=0.25)
    gen = GenerateConfig(frames=400, seed=5, episode_frames=200, warmup=0.0,
                         options=drive_options(cfg, 1, Path(model)))
    generate(tmp_path / "d", gen, workers=2, show_progress=False, plugin=AggregationPlugin())
    labels = Dataset(tmp_path / "d").labels(None, ["perturbation"])["perturbation"]
    assert abs(np.mean(labels != "learner") - 0.25) < 0.07     # 400 draws: 3 standard deviations is 0.065


def test_the_same_seed_drives_the_same_round(model, tmp_path):
    cfg = AggregationConfig(data=str(dataset()), model=str(model), out=str(tmp_path))
    digests = []
    for name in ("a", "b"):
        gen = GenerateConfig(frames=20, seed=7, episode_frames=20, warmup=1.0,
                             options=drive_options(cfg, 1, Path(model)))
        manifest = generate(tmp_path / name, gen, workers=1, show_progress=False, plugin=AggregationPlugin())
        digests.append([s["sha256"] for s in manifest["shards"]])
    assert digests[0] == digests[1]


def test_a_round_draws_with_the_expert_datasets_renderer(model, tmp_path):
    expert = tmp_path / "expert"   # the shared dataset's frames, its manifest naming TinyRenderer as their renderer
    shutil.copytree(dataset(), expert, ignore=shutil.ignore_patterns(".frames"))
    manifest = json.loads((expert / MANIFEST).read_text())
    manifest["renderer"] = "tiny"
    (expert / MANIFEST).write_text(json.dumps(manifest))
    r = ds("aggregate", "--data", expert, "--model", model, "--out", tmp_path / "run", *SMALL)
    assert r.returncode == 0, r.stderr
    assert Dataset(tmp_path / "run" / "round-1" / "data").renderers == ("tiny",)


def test_running_again_continues_and_other_options_are_refused(run, model):
    r = ds("aggregate", "--data", dataset(), "--model", model, "--out", run, *SMALL)
    assert r.returncode == 0 and "driving" not in r.stdout      # round 1 is done: nothing is driven again
    r = ds("aggregate", "--config", run / "config.json")
    assert r.returncode == 0 and "driving" not in r.stdout      # and from the run's config.json
    r = ds("aggregate", "--data", dataset(), "--model", model, "--out", run, *SMALL, "--set", "frames=80")
    assert r.returncode == 2 and "other options (frames differ)" in r.stderr and len(r.stderr.splitlines()) == 1


def test_a_run_made_before_emphasis_continues_and_another_emphasis_is_refused(tmp_path):
    from drivestudio.errors import UsageError
    from drivestudio.worlds.highway.aggregation import STATE, Aggregation

    cfg = AggregationConfig(data="d", model="m.pt", out=str(tmp_path / "run"))
    Aggregation(cfg)._save()
    state = json.loads((tmp_path / "run" / STATE).read_text())
    del state["config"]["emphasis"]      # as written before the option existed
    (tmp_path / "run" / STATE).write_text(json.dumps(state))
    assert Aggregation(cfg).state["config"]["emphasis"] == 1
    with pytest.raises(UsageError, match="emphasis differ"):
        Aggregation(AggregationConfig(data="d", model="m.pt", out=str(tmp_path / "run"), emphasis=3))


@pytest.mark.parametrize("args, message", [
    (["--rounds", "0"], "--rounds"),
    (["--set", "beta=1.5"], "--set beta"),
    (["--set", "cars=40-12"], "cars must be from 0 to 300"),
    (["--set", "emphasis=0"], "--set emphasis"),
    (["--suite", "/nonexistent/suite.json"], "no such file"),
])
def test_bad_input_is_refused_in_one_line_before_any_work(model, tmp_path, args, message):
    out = tmp_path / "never"
    r = ds("aggregate", "--data", dataset(), "--model", model, "--out", out, *args)
    assert r.returncode == 2 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (out / "round-1").exists()


def test_a_model_of_the_other_world_is_refused(tmp_path):
    from core.worlds.sidewalk import SIDEWALK
    from perception.checkpoint import save_checkpoint
    from perception.models import build
    ckpt = tmp_path / "z2color.pt"
    model = build("z2color", SIDEWALK)
    save_checkpoint(ckpt, {"spec": model.spec, "state_dict": model.state_dict()})
    r = ds("aggregate", "--data", dataset(), "--model", ckpt, "--out", tmp_path / "x")
    assert r.returncode == 2 and "sidewalk world" in r.stderr
