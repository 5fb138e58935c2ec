"""The moving average of the weights (perception/weight_average.py) and the trainer's use of it: the rule, the
batch-norm statistics, what a checkpoint holds, and an interrupted run continuing exactly."""
import pytest
import torch
from torch import nn

from perception.checkpoint import CheckpointError, load_checkpoint
from perception.train import train
from perception.weight_average import WeightAverage
from tests.perception.frames import tiny_config, workdir


def test_the_first_update_copies_and_each_later_one_moves_a_decay_fraction():
    model = nn.Linear(2, 1, bias=False)
    with torch.no_grad():
        model.weight.copy_(torch.tensor([[1.0, -2.0]]))
    avg = WeightAverage(model, 0.9)
    avg.update(model)
    assert torch.equal(avg.module.weight, torch.tensor([[1.0, -2.0]]))
    with torch.no_grad():
        model.weight.copy_(torch.tensor([[3.0, 0.0]]))
    avg.update(model)
    # 0.9 * old + 0.1 * new
    torch.testing.assert_close(avg.module.weight, torch.tensor([[1.2, -1.8]]))
    assert avg.steps == 2


def test_batch_norm_statistics_are_averaged_too():
    model = nn.BatchNorm1d(1)
    avg = WeightAverage(model, 0.5)
    avg.update(model)                       # running mean 0
    model(torch.tensor([[10.0], [10.0]]))   # running mean 0.9 * 0 + 0.1 * 10 = 1
    avg.update(model)
    assert float(avg.module.running_mean) == pytest.approx(0.5)


def test_a_decay_outside_0_1_is_refused():
    for decay in (0.0, 1.0, 1.5):
        with pytest.raises(ValueError):
            WeightAverage(nn.Linear(1, 1), decay)


def test_the_checkpoint_holds_the_average_and_an_interrupted_run_continues_exactly():
    straight, halves = workdir() / "ema-straight.pt", workdir() / "ema-halves.pt"
    train(tiny_config("mobilenet", straight, iterations=8, ema=0.9), log=lambda *x: None)
    train(tiny_config("mobilenet", halves, iterations=4, ema=0.9), log=lambda *x: None)
    train(tiny_config("mobilenet", halves, iterations=8, ema=0.9), log=lambda *x: None)
    a, b = load_checkpoint(straight), load_checkpoint(halves)
    assert a["train"]["config"]["ema"] == 0.9 and a["train"]["averaged_steps"] == 8
    key = "net.regressor.1.weight"
    # what is used (state_dict) is the average, not the weights trained
    assert not torch.allclose(a["state_dict"][key], a["training_state_dict"][key])
    for part in ("state_dict", "training_state_dict"):
        torch.testing.assert_close(b[part][key], a[part][key], rtol=1e-4, atol=1e-5)
    with pytest.raises(CheckpointError, match="ema=0.9"):
        train(tiny_config("mobilenet", halves, iterations=10, ema=0.0), log=lambda *x: None)


def test_without_an_average_the_checkpoint_holds_the_trained_weights_alone():
    path = workdir() / "no-ema.pt"
    train(tiny_config("mobilenet", path, iterations=2, ema=0.0), log=lambda *x: None)
    ckpt = load_checkpoint(path)
    assert "training_state_dict" not in ckpt and ckpt["train"]["config"]["ema"] == 0.0
