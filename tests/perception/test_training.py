"""Short real training runs on generated frames: the loss goes down, checkpoints resume where they stopped."""
import csv

import numpy as np
import pytest
import torch

from core.worlds.highway import HIGHWAY, label_set
from perception.checkpoint import CheckpointError, load_checkpoint
from perception.curves import curve_paths
from perception.datasets import DatasetError, FrameDataset, FrameStream
from perception.models import family
from perception.shards import Dataset
from perception.train import train
from perception.training import TrainConfig, absolute_loss, euclidean_loss
from tests.perception.frames import alexnet_checkpoint, dataset, gist_checkpoint, tiny_config, workdir


def test_paper_settings_are_the_defaults():
    cfg = TrainConfig()
    assert (cfg.optimizer, cfg.momentum, cfg.lr_step, cfg.lr_gamma) == (None, 0.9, 1000, 0.9)   # None: sgd
    assert family("alexnet").defaults == {"iterations": 10_000, "batch_size": 15, "lr": 1e-2}
    assert family("vgg16").defaults == {"iterations": 15_000, "batch_size": 10, "lr": 1e-4}


def test_euclidean_loss_is_half_the_mean_squared_norm():
    pred, target = torch.tensor([[1.0, 2.0], [0.0, 0.0]]), torch.tensor([[0.0, 0.0], [0.0, 3.0]])
    assert float(euclidean_loss(pred, target)) == pytest.approx((5 + 9) / (2 * 2))


def test_absolute_loss_is_the_mean_l1_norm():
    pred, target = torch.tensor([[1.0, -2.0], [0.0, 0.0]]), torch.tensor([[0.0, 0.0], [0.0, 3.0]])
    assert float(absolute_loss(pred, target)) == pytest.approx((3 + 3) / 2)


def test_absolute_loss_pulls_every_output_alike_whatever_its_error():
    """The reason for --loss l1: an error of 0.01 and one of 0.5 get gradients of the same size (the Euclidean
    loss's would differ fifty-fold)."""
    pred = torch.tensor([[0.51, 1.0], [0.49, 0.0]], requires_grad=True)
    absolute_loss(pred, torch.tensor([[0.5, 0.5], [0.5, 0.5]])).backward()
    assert torch.equal(pred.grad, torch.tensor([[0.5, 0.5], [-0.5, -0.5]]))
    pred.grad = None
    euclidean_loss(pred, torch.tensor([[0.5, 0.5], [0.5, 0.5]])).backward()
    assert pred.grad[0, 1] / pred.grad[0, 0] == pytest.approx(50)


def test_the_loss_setting_offers_every_loss_and_no_other():
    from core.settings import entries
    from perception.training import LOSSES

    assert entries(TrainConfig)["loss"].setting.choices == tuple(LOSSES)


def test_l1_training_records_its_loss_and_continues_only_with_it():
    path = workdir() / "mobilenet-l1.pt"
    train(tiny_config("mobilenet", path, iterations=2, loss="l1"), log=lambda *x: None)
    ckpt = load_checkpoint(path)
    assert ckpt["train"]["config"]["loss"] == "l1"
    # its validation loss is the L1 one: near the training loss, not a tenth of it as a Euclidean value would be
    row = ckpt["train"]["history"][-1]
    assert row["val_loss"] > 0.3 * row["train_loss"]
    with pytest.raises(CheckpointError, match="loss=l1"):
        train(tiny_config("mobilenet", path, iterations=4, loss="euclidean"), log=lambda *x: None)
    # without a loss it continues with the checkpoint's, and so does a run that starts from it (init)
    train(tiny_config("mobilenet", path, iterations=4), log=lambda *x: None)
    assert load_checkpoint(path)["train"]["config"]["loss"] == "l1"
    tuned = workdir() / "mobilenet-l1-tuned.pt"
    train(tiny_config("mobilenet", tuned, iterations=2, init=str(path)), log=lambda *x: None)
    assert load_checkpoint(tuned)["train"]["config"]["loss"] == "l1"


def test_emphasis_trains_on_the_decisive_frames_repeated_and_records_it():
    path = workdir() / "mobilenet-emphasis.pt"
    lines: list[str] = []
    train(tiny_config("mobilenet", path, iterations=2, emphasis=4), log=lines.append)
    plain = FrameStream(dataset(), "train")
    repeated = FrameStream(dataset(), "train", emphasis=4)
    assert len(repeated) > len(plain)     # the tiny set's traffic holds decisive frames
    assert any(f"on {len(repeated)} frames" in line and "decisive frames 4 times each" in line for line in lines)
    assert load_checkpoint(path)["train"]["config"]["emphasis"] == 4


def test_emphasis_counts_the_decisive_labels_among_the_targets_only():
    """A network of the paper's 13 is emphasised on a near car ahead in any lane, one that learns the host lane's
    gap alone on a near car in the host's lane, each step as its labels say; a network of none of the decisive
    labels (the cars behind) is refused."""
    data = Dataset(dataset())
    for targets, names in ((HIGHWAY.targets, ("dist_LL", "dist_MM", "dist_RR", "dist_L", "dist_R")),
                           (("angle", "dist_MM"), ("dist_MM",))):
        stream = FrameStream(dataset(), "train", targets=targets, emphasis=3)
        for k, shard in enumerate(stream.shards):
            table = data.reader(shard).labels(names)
            near = np.logical_or.reduce([table.column(n).to_numpy() < 20.0 for n in names])
            np.testing.assert_array_equal(stream.times[k], np.where(near, 3, 1))
    wide, narrow = (sum(int(n.sum()) for n in FrameStream(dataset(), "train", targets=t, emphasis=3).times.values())
                    for t in (HIGHWAY.targets, ("angle", "dist_MM")))
    assert wide > narrow   # the tiny set's near cars are in a neighbouring lane: they count only where learned
    with pytest.raises(DatasetError, match="none of the highway world's decisive labels"):
        FrameStream(dataset(), "train", targets=("fast", "dist_LB", "dist_RB"), emphasis=3)


@pytest.mark.long   # an AlexNet trained on real frames until its loss falls: 11 s
def test_alexnet_training_lowers_the_loss_on_real_frames():
    path, record = alexnet_checkpoint()
    history = record["history"]
    assert record["iteration"] == 8
    assert history[-1]["train_loss"] < 0.8 * history[0]["train_loss"]
    vals = [r["val_loss"] for r in history if r.get("val_loss") is not None]
    assert len(vals) == 2 and vals[-1] < history[0]["train_loss"]


def test_alexnet_checkpoint_carries_everything_needed_to_use_and_resume_it():
    path, _ = alexnet_checkpoint()
    ckpt = load_checkpoint(path, model="alexnet", labels=label_set())
    assert ckpt["spec"]["name"] == "alexnet" and ckpt["spec"]["labels"] == list(label_set())
    assert len(ckpt["spec"]["input"]["mean"]) == 3 and ckpt["spec"]["normalisation"]["dist_MM"][1] == 0.12
    assert {"optimizer", "scheduler", "rng", "train", "data"} <= set(ckpt)
    assert ckpt["data"]["frames"]["train"] == FrameDataset(dataset(), "train").__len__()
    assert ckpt["train"]["config"]["optimizer"] == "sgd" and ckpt["train"]["finished"]


def test_loss_curves_are_written_beside_the_checkpoint():
    path, _ = alexnet_checkpoint()
    csv_path, png_path = curve_paths(path)
    rows = list(csv.DictReader(csv_path.open()))
    assert [int(r["iteration"]) for r in rows] == [2, 4, 6, 8]
    assert rows[1]["val_loss"] and not rows[0]["val_loss"]
    assert png_path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.long
def test_rerunning_the_same_training_continues_from_the_checkpoint():
    """4 iterations, then the same training to 8, ends where the straight 8-iteration run ended (same data
    order, same optimiser state, same learning-rate schedule)."""
    straight, _ = alexnet_checkpoint()
    path = workdir() / "resumed.pt"
    train(tiny_config("alexnet", path, iterations=4), log=lambda *x: None)
    assert load_checkpoint(path)["train"]["iteration"] == 4
    train(tiny_config("alexnet", path, iterations=8), log=lambda *x: None)
    resumed, ref = load_checkpoint(path), load_checkpoint(straight)
    assert resumed["train"]["iteration"] == 8
    assert [r["iteration"] for r in resumed["train"]["history"]] == [2, 4, 6, 8]
    for k in ("net.regressor.6.weight", "net.features.0.weight"):
        torch.testing.assert_close(resumed["state_dict"][k], ref["state_dict"][k], rtol=1e-4, atol=1e-5)
    assert resumed["scheduler"]["last_epoch"] == 8
    # a finished run has nothing left to do
    again = train(tiny_config("alexnet", path, iterations=8), log=lambda *x: None)
    assert again["iteration"] == 8


def test_gist_fit_beats_predicting_the_training_mean():
    path, record = gist_checkpoint()
    sweep = record["history"]
    assert len(sweep) > 3 and all({"alpha", "train_loss", "val_loss"} <= set(r) for r in sweep)
    train_targets = torch.stack([y for _, _, y in FrameDataset(dataset(), "train")])
    val_targets = torch.stack([y for _, _, y in FrameDataset(dataset(), "val")])
    constant = euclidean_loss(train_targets.mean(0).expand_as(val_targets), val_targets)
    assert min(r["val_loss"] for r in sweep) < float(constant)
    assert curve_paths(path)[0].exists() and curve_paths(path)[1].exists()


def test_gist_checkpoint_has_no_pickled_code_and_no_optimiser():
    path, _ = gist_checkpoint()
    ckpt = torch.load(path, weights_only=True)
    assert ckpt["spec"]["name"] == "gist" and ckpt["spec"]["options"]["regressor"] == "ridge"
    assert "optimizer" not in ckpt
    assert ckpt["state_dict"]["net.weight"].shape == (512, 13)


@pytest.mark.slow
def test_vgg16_frozen_trains_its_head_from_a_random_trunk_and_says_so(tmp_path):
    said = []
    record = train(tiny_config("vgg16", tmp_path / "vgg.pt", iterations=4, batch_size=2, lr=1e-4),
                   log=said.append)
    assert any("RANDOM initialisation" in line for line in said)
    assert record["iteration"] == 4
    ckpt = load_checkpoint(tmp_path / "vgg.pt", model="vgg16")
    assert ckpt["spec"]["options"] == {"weights": None, "frozen": True, "batch_norm": False}


def test_a_channels_last_stream_batches_the_same_values_channels_last():
    """FrameStream.channels_last changes the images' memory layout only: the same samples in the same order, and
    collate_channels_last makes of them the batch default_collate makes, already channels-last (what the trainer
    converts its batches to) and with the history's frames in their channel order."""
    from perception.datasets import collate_channels_last
    from perception.training import history_moment

    moment = history_moment(HIGHWAY, 1)
    plain = FrameStream(dataset(), "train", seed=5, moment=moment)
    fast = FrameStream(dataset(), "train", seed=5, moment=moment)
    fast.channels_last = True
    a = list(zip(range(6), plain))
    b = list(zip(range(6), fast))
    for (_, sa), (_, sb) in zip(a, b):
        assert torch.equal(sa[0], sb[0]) and torch.equal(sa[2], sb[2])
        assert sb[0].shape == (6, 210, 280) and sb[0].permute(1, 2, 0).is_contiguous()
    batch = collate_channels_last([s for _, s in b])
    want = torch.utils.data.default_collate([s for _, s in a])
    assert batch[0].is_contiguous(memory_format=torch.channels_last)
    assert all(torch.equal(x, y) for x, y in zip(batch, want))
