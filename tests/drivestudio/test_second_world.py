"""A second world, declared by a test (tests/drivestudio/tiny_world.py: two cameras, its own labels and action, data
moments that reach back one step and ahead two), goes through `generate`, the readers, training of a tiny model and a
two-process run over the bridge, with no change to the loop, the bridge, the shard or the training code."""
import json
import os
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest

from perception.datasets import FrameDataset
from perception.shards import Dataset
from tests.helpers import make
from tests.shm_bridge.processes import REPO

WORLDS = {"DRIVESTUDIO_WORLDS": "tests.drivestudio.tiny_world:Plugin", "PYTHONPATH": str(REPO)}
ENV = {**os.environ, **WORLDS}
STEPS = 30   # per episode


def cli(*args, check=True):
    r = subprocess.run([sys.executable, "-m", "drivestudio", *map(str, args)], cwd=REPO, env=ENV,
                       capture_output=True, text=True, timeout=300)
    if check:
        assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("corridor") / "ds"
    make("generate", "--world", "corridor", "--out", root, "--frames", 10 * STEPS, "--episode-frames", STEPS,
         "--workers", 2, env=WORLDS)
    return root


@pytest.fixture(scope="module")
def checkpoint(data, tmp_path_factory):
    out = tmp_path_factory.mktemp("corridor-model") / "tiny.pt"
    make("train", "--data", data, "--model", "tinyconv", "--out", out, "--iterations", 150, "--batch-size", 16,
         "--set", "val_every=50", "--set", "optimizer=adam", "--lr", "3e-3", "--device", "cpu", env=WORLDS)
    return out


def test_generate_writes_the_declared_columns(data):
    ds = Dataset(data)
    assert ds.world == "corridor" and ds.frames() == 10 * STEPS and len(ds.shards) == 10
    names = pq.read_schema(data / ds.shards[0].file).names
    assert names == ["image_near", "image_far", "turn", "go", "offset", "yaw", "bumped", "episode", "step", "t",
                     "seed", "action"]
    images, rec = ds.reader(ds.shards[4]).row(5)
    assert [img.shape for img in images] == [(12, 20, 3), (12, 20, 3)]
    assert rec["episode"] == 4 and rec["step"] == 5 and len(rec["action"]) == 2
    assert [s.params["start"] for s in ds.shards[3:6]] == pytest.approx([-0.8, 0.0, 0.8])   # its own plan


def test_moments_reach_back_one_step_and_ahead_two(data):
    ds = FrameDataset(data, split="train", normalised=False)
    assert ds.outputs == ("turn+1", "turn+2", "go+1", "go+2")
    assert len(ds) == 8 * (STEPS - 1 - 2)          # a moment needs the step before and the two after
    shard = Dataset(data).reader(ds.shards[0])
    for i in (0, 13, 26):
        k, t = ds.locate(i)
        assert k == 0 and t == i + 1                 # the first moment starts at the second step
        images, mode, target = ds[i]
        assert images.shape == (12, 12, 20) and mode.item() == -1
        before, now = shard.row(t - 1), shard.row(t)
        after = [shard.row(t + 1)[1], shard.row(t + 2)[1]]
        np.testing.assert_array_equal(images[0:3].numpy().transpose(1, 2, 0), before[0][0])   # near, t - 1
        np.testing.assert_array_equal(images[3:6].numpy().transpose(1, 2, 0), before[0][1])   # far, t - 1
        np.testing.assert_array_equal(images[6:9].numpy().transpose(1, 2, 0), now[0][0])      # near, t
        np.testing.assert_array_equal(images[9:12].numpy().transpose(1, 2, 0), now[0][1])     # far, t
        assert now[1]["t"] - before[1]["t"] == pytest.approx(0.1)                             # one step older
        np.testing.assert_allclose(target.numpy(), [after[0]["turn"], after[1]["turn"], after[0]["go"],
                                                    after[1]["go"]], rtol=1e-6)


def test_a_tiny_model_learns_the_corridor(checkpoint):
    from perception.checkpoint import load_checkpoint
    ckpt = load_checkpoint(checkpoint)
    assert ckpt["spec"]["world"] == "corridor" and ckpt["spec"]["input"]["channels"] == 12
    history = [r for r in ckpt["train"]["history"] if r.get("train_loss") is not None]
    assert history[-1]["train_loss"] < 0.5 * history[0]["train_loss"]


@pytest.mark.long
def test_it_drives_over_the_bridge_in_two_processes(checkpoint, tmp_path):
    r = cli("drive", "--world", "corridor", "--model", checkpoint, "--seconds", 5, "--start-offset", 1.0,
            "--out", tmp_path)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["transport"] == "shared memory" and metrics["world"] == "corridor" and metrics["steps"] == 50
    assert metrics["bumps"] == 0 and metrics["max_offset_m"] < 2.0
    assert "the world ended the run: finished" in r.stderr


def test_its_options_and_models_stay_in_their_world(checkpoint, run_cli, tmp_path):
    r = run_cli("drive", "--world", "highway", "--start-offset", 1.0, "--seconds", 1, env=WORLDS, cwd=REPO)
    assert r.returncode == 2 and "--start-offset belongs to the corridor world" in r.stderr
    r = run_cli("drive", "--world", "highway", "--model", checkpoint, "--seconds", 1, "--in-process", "--out",
                tmp_path, env=WORLDS, cwd=REPO)
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert "a model of the corridor world, not of the highway world" in r.stderr
