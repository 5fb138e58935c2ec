"""The MobileNet family (perception/mobilenet.py): half-resolution input, one output per label, earlier frames as
more channels, a checkpoint that continues or starts a new run from its weights, and the Chen driver that feeds a
temporal model its history."""
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from core.worlds.highway import HIGHWAY, label_set
from drivestudio.worlds.highway.drivers import ChenDriver
from perception.checkpoint import CheckpointError
from perception.evaluate import evaluate_model
from perception.models import build, load_model
from perception.predictor import load_predictor
from perception.shards import Dataset
from perception.train import train
from tests.perception.frames import dataset, tiny_config, workdir


def test_it_reads_the_frame_at_half_resolution_and_predicts_every_label():
    model = build("mobilenet", HIGHWAY, label_set(fast=True))
    assert model.size == (105, 140)
    out = model(torch.randint(0, 256, (2, 3, 210, 280), dtype=torch.uint8))
    assert out.shape == (2, 14)


def test_earlier_frames_are_more_channels_oldest_first():
    model = build("mobilenet", HIGHWAY, instants=(-2, -1, 0))
    assert model.spec["input"]["channels"] == 9 and model.spec["input"]["instants"] == [-2, -1, 0]
    assert model(torch.zeros(1, 9, 210, 280, dtype=torch.uint8)).shape == (1, 13)


def test_a_family_without_history_refuses_earlier_frames():
    with pytest.raises(CheckpointError, match="instants"):
        build("alexnet", HIGHWAY, instants=(-1, 0))


@pytest.fixture(scope="module")
def temporal():
    out = workdir() / "mobilenet-h1.pt"
    train(tiny_config("mobilenet", out, history=1), log=lambda *a: None)
    return out


def test_a_temporal_model_trains_and_its_checkpoint_says_so(temporal):
    model, ckpt = load_model(temporal)
    assert ckpt["spec"]["input"]["instants"] == [-1, 0] and ckpt["train"]["iteration"] == 8


def test_continuing_with_another_history_is_refused(temporal):
    with pytest.raises(CheckpointError, match="the same history"):
        train(tiny_config("mobilenet", temporal, history=0, iterations=12), log=lambda *a: None)


def test_init_starts_a_new_run_from_the_weights(temporal):
    out = workdir() / "mobilenet-h1-tuned.pt"
    train(tiny_config("mobilenet", out, history=1, iterations=1, init=str(temporal), lr=1e-12), log=lambda *a: None)
    a = torch.load(temporal, weights_only=True)["state_dict"]
    b = torch.load(out, weights_only=True)["state_dict"]
    weights = [k for k in a if k.endswith("weight")]
    assert all(torch.allclose(a[k], b[k], atol=1e-6) for k in weights)   # one step at lr 1e-12 moves nothing
    assert torch.load(out, weights_only=True)["train"]["iteration"] == 1


def test_the_chen_driver_feeds_a_temporal_model_the_previous_frame(temporal):
    predictor = load_predictor(temporal)
    seen = []

    def spy(images):
        seen.append([int(f[0, 0, 0]) for f in images])
        return np.zeros(len(predictor.outputs))

    spy.name, spy.outputs, spy.instants = "spy", predictor.outputs, predictor.instants
    driver = ChenDriver(spy)
    record = HIGHWAY.pack({k: 0.0 for k in HIGHWAY.truth_names})
    record[HIGHWAY.index("lanes")] = 3
    for value in (1, 2, 3):
        frame = np.full((210, 280, 3), value, np.uint8)
        driver.estimate(SimpleNamespace(frames=(frame,), record=record, t=0.0))
    assert seen == [[1, 1], [1, 2], [2, 3]]   # (previous, current); the first frame stands in for the missing one


def test_evaluate_feeds_a_temporal_model_its_earlier_frame(temporal):
    """The MAE report reads the frames the model reads (previous and current), not one frame of three channels,
    and measures every step that has its earlier frame."""
    result = evaluate_model(temporal, str(dataset()), split="all", latency_frames=3, log=lambda *a: None)
    one_instant = evaluate_model(workdir_model_one_instant(), str(dataset()), split="all", latency_frames=3,
                                 log=lambda *a: None)
    assert np.isfinite(result.errors).all() and result.errors.shape[1] == 13
    episodes = len({s.episode for s in Dataset(dataset()).shards})
    assert len(one_instant.errors) - len(result.errors) == episodes   # each episode's first step has no previous


def workdir_model_one_instant():
    out = workdir() / "mobilenet-h0.pt"
    if not out.exists():
        train(tiny_config("mobilenet", out, iterations=1), log=lambda *a: None)
    return out
