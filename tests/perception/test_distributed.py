"""Training on several processes: `torchrun --nproc_per_node 2 -m drivestudio train` on the CPU (gloo) trains and
checkpoints like the single-process run (perception/train_sgd.py, docs/scaling.md). The corridor world of
tests/drivestudio/tiny_world.py and its tiny model keep it to seconds."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from perception.checkpoint import load_checkpoint
from perception.curves import curve_paths
from perception.datasets import FrameStream
from perception.predictor import load_predictor
from perception.shards import Dataset
from tests.perception.frames import dataset

REPO = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "DRIVESTUDIO_WORLDS": "tests.drivestudio.tiny_world:Plugin", "PYTHONPATH": str(REPO),
       "OMP_NUM_THREADS": "1"}
TORCHRUN = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2"]
TRAIN = ["--model", "tinyconv", "--batch-size", "8", "--set", "val_every=20", "--set", "optimizer=adam", "--lr", "3e-3",
         "--device", "cpu", "--workers", "1"]


def episodes_read(stream: FrameStream, workers: int = 1) -> list[set]:
    """The shards each DataLoader worker of `stream` reads in its epoch (as DataLoader workers would)."""
    from unittest import mock
    out = []
    for w in range(workers):
        info = mock.Mock(id=w, num_workers=workers) if workers > 1 else None
        with mock.patch("torch.utils.data.get_worker_info", return_value=info):
            out.append(set(stream._my_shards()[0]))
    return out


def test_each_rank_reads_a_disjoint_part_of_the_episodes_every_epoch():
    root = dataset()
    whole = FrameStream(root, "train", seed=3)
    n = len(whole.shards)
    for epoch in (0, 1):
        parts = []
        for rank in range(2):
            s = FrameStream(root, "train", seed=3, rank=rank, world_size=2)
            s.set_epoch(epoch)
            per_worker = episodes_read(s, workers=2)
            assert not per_worker[0] & per_worker[1]
            parts.append(per_worker[0] | per_worker[1])
            # the whole epoch's batches of this rank's DataLoader: each worker drops its partial batch
            sizes = [sum(len(s.spec.starts(s.shards[k].frames)) for k in p) for p in per_worker]
            assert s.batches(4, workers=2) == sum(x // 4 for x in sizes)
        assert not parts[0] & parts[1] and parts[0] | parts[1] == set(range(n))
        whole.set_epoch(epoch)
        order = whole._my_shards()[0]
        assert parts[0] == set(order[0::2]) and parts[1] == set(order[1::2])   # the same shuffled order on both
    one = FrameStream(root, "train", seed=3)
    assert one.batches(4) == len(one) // 4 and one.batches(4, workers=1) == len(one) // 4
    with pytest.raises(ValueError):
        FrameStream(root, "train", rank=2, world_size=2)


# --- real processes ------------------------------------------------------------------------------------------
def cli(*args, launcher=(sys.executable, "-m", "drivestudio"), timeout=600):
    r = subprocess.run([*launcher, *map(str, args)], cwd=REPO, env=ENV, capture_output=True, text=True,
                       timeout=timeout)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return r


def torchrun(*args):
    return cli(*args, launcher=(*TORCHRUN, "-m", "drivestudio"))


@pytest.fixture(scope="module")
def corridor(tmp_path_factory):
    root = tmp_path_factory.mktemp("corridor") / "ds"
    cli("generate", "--world", "corridor", "--out", root, "--frames", 300, "--episode-frames", 30, "--workers", 2)
    return root


@pytest.fixture(scope="module")
def single(corridor, tmp_path_factory):
    out = tmp_path_factory.mktemp("single") / "one.pt"
    cli("train", "--data", corridor, "--out", out, "--iterations", 40, *TRAIN)
    return out


@pytest.fixture(scope="module")
def distributed(corridor, tmp_path_factory):
    out = tmp_path_factory.mktemp("ddp") / "two.pt"
    r = torchrun("train", "--data", corridor, "--out", out, "--iterations", 40, *TRAIN)
    return out, r


@pytest.mark.slow
def test_torchrun_trains_and_checkpoints_like_a_single_process(distributed, single):
    path, r = distributed
    assert "2 processes (gloo), 8 samples each per iteration, 16 in all" in r.stdout
    assert r.stdout.count("saved ") == 1            # rank 0 alone reports (and writes)
    two, one = load_checkpoint(path, model="tinyconv"), load_checkpoint(single, model="tinyconv")
    assert set(two) == set(one)                      # the same checkpoint format
    assert set(two["state_dict"]) == set(one["state_dict"])   # the model's keys, not DDP's "module." ones
    assert set(two["train"]) - set(one["train"]) == {"world_size"} and two["train"]["world_size"] == 2
    assert two["spec"] == one["spec"]                # same input statistics: rank 0's, shared
    assert two["train"]["iteration"] == 40 and two["train"]["finished"]
    assert two["train"]["config"]["batch_size"] == 8 and two["optimizer"]["state"]
    history = two["train"]["history"]
    assert [row["iteration"] for row in history] == [10, 20, 30, 40]
    assert history[-1]["train_loss"] < 0.5 * history[0]["train_loss"]   # it learns
    assert [row["iteration"] for row in history if row.get("val_loss") is not None] == [20, 40]
    # 40 iterations of 2 x 8 samples cover twice the samples of the single process's 40 iterations of 8
    assert history[-1]["epoch"] == pytest.approx(2 * one["train"]["history"][-1]["epoch"], abs=1e-3)
    csv_path, png_path = curve_paths(path)
    assert csv_path.read_text().count("\n") == 5 and png_path.stat().st_size > 0


@pytest.mark.slow
def test_a_torchrun_checkpoint_loads_as_a_predictor(distributed, corridor):
    from drivestudio import worlds
    from tests.drivestudio import tiny_world

    worlds.register(tiny_world.Plugin())   # this process learns the corridor world (the CLI's do by DRIVESTUDIO_WORLDS)
    path, _ = distributed
    predictor = load_predictor(path, world="corridor")
    data = Dataset(corridor)
    reader = data.reader(data.shards[9])
    before, now = reader.row(4)[0], reader.row(5)[0]
    named = predictor.named([*before, *now])          # the moment: (t - 1, t), cameras near and far
    assert list(named) == ["turn+1", "turn+2", "go+1", "go+2"] and np.isfinite(list(named.values())).all()


@pytest.mark.slow
def test_torchrun_resumes_from_its_checkpoint(corridor, distributed, tmp_path):
    straight, _ = distributed
    path = tmp_path / "resumed.pt"
    torchrun("train", "--data", corridor, "--out", path, "--iterations", 20, *TRAIN)
    assert load_checkpoint(path)["train"]["iteration"] == 20
    r = torchrun("train", "--data", corridor, "--out", path, "--iterations", 40, *TRAIN)
    assert "continuing" in r.stdout
    resumed, ref = load_checkpoint(path), load_checkpoint(straight)
    assert resumed["train"]["iteration"] == 40
    assert [row["iteration"] for row in resumed["train"]["history"]] == [10, 20, 30, 40]
    for k, v in ref["state_dict"].items():           # same data order, same optimiser state: the same weights
        torch.testing.assert_close(resumed["state_dict"][k], v, rtol=1e-4, atol=1e-5)
