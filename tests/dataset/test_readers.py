"""The PyTorch readers on a real generated highway dataset (the moments of a stereo world: tests/drivestudio/
test_second_world.py and tests/sidewalk)."""

import numpy as np
import pytest
import torch

from core.worlds.highway import HIGHWAY, PAPER_INDICATORS, label_set
from perception.datasets import FrameDataset, FrameStream
from perception.shards import DatasetError


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("readers") / "ds"
    from tests.helpers import make
    make("generate", "--out", root, "--frames", "200", "--episode-frames", "20", "--tracks", "oval", "--lanes", "3",
         "--cars", "6", "--workers", "2")
    return root


def test_map_style_random_access(data):
    ds = FrameDataset(data, split="train", targets=label_set(fast=True))
    assert len(ds) == 160  # episodes 0-7 of 10
    img, mode, target = ds[37]
    assert img.shape == (3, 210, 280) and img.dtype == torch.uint8
    assert mode.item() == -1   # the highway has no behavioural modes
    assert target.shape == (14,) and target.dtype == torch.float32
    raw_images, record = ds.record(37)
    np.testing.assert_array_equal(img.numpy().transpose(1, 2, 0), raw_images[0])
    values = HIGHWAY.denormalise(target.numpy(), label_set(fast=True))
    for name, v in zip(label_set(fast=True), values):
        expected = record[name]
        if name == "angle" and abs(expected) > 0.55:
            continue  # angle's normalisation clips beyond ±0.55 rad
        assert v == pytest.approx(expected, abs=1e-3), name
    # neighbouring indices in one shard and across shards
    for i in (0, 19, 20, 159):
        assert ds[i][0].shape == (3, 210, 280)
    with pytest.raises(IndexError):
        ds[160]


def test_splits_partition_the_frames(data):
    sizes = {s: len(FrameDataset(data, split=s)) for s in ("train", "val", "test")}
    assert sizes == {"train": 160, "val": 20, "test": 20}


def test_stream_yields_every_frame_once_in_shuffled_order(data):
    stream = FrameStream(data, split="train", targets=PAPER_INDICATORS, seed=1, buffer=64)
    targets = [t for _, _, t in stream]
    assert len(targets) == 160
    ordered = FrameDataset(data, split="train")
    reference = {tuple(np.round(ordered[i][2].numpy(), 5)) for i in range(len(ordered))}
    assert {tuple(np.round(t.numpy(), 5)) for t in targets} == reference
    first = [tuple(np.round(t.numpy(), 5)) for _, _, t in FrameStream(data, split="train", seed=1, buffer=64)]
    assert first != [tuple(np.round(ordered[i][2].numpy(), 5)) for i in range(len(ordered))]  # shuffled


def test_stream_in_order_matches_random_access_and_carries_context(data):
    ordered = FrameDataset(data, split="test", normalised=False)
    stream = list(FrameStream(data, split="test", normalised=False, shuffle=False, context=("lanes", "speed")))
    assert len(stream) == len(ordered) == 20
    for i in (0, 7, 19):
        img, _, target, context = stream[i]
        np.testing.assert_array_equal(img.numpy(), ordered[i][0].numpy())
        np.testing.assert_array_equal(target.numpy(), ordered[i][2].numpy())
        _, record = ordered.record(i)
        assert context[0].item() == record["lanes"] == 3
        assert context[1].item() == pytest.approx(record["speed"], rel=1e-6)


def test_stream_splits_shards_across_dataloader_workers(data):
    loader = torch.utils.data.DataLoader(FrameStream(data, split="train", seed=0), batch_size=16, num_workers=2)
    images = torch.cat([x for x, _, _ in loader])
    assert images.shape == (160, 3, 210, 280)


def test_missing_labels_and_split_are_errors(data):
    with pytest.raises(DatasetError, match="no labels"):
        FrameDataset(data, targets=("angle", "colour"))
    with pytest.raises(DatasetError, match="unknown split"):
        FrameDataset(data, split="holdout")
    with pytest.raises(DatasetError, match="not a dataset"):
        FrameDataset(data.parent)
    with pytest.raises(DatasetError, match="no column colour"):
        FrameStream(data, context=("colour",))


DECISIVE = ("dist_LL", "dist_RR", "dist_L", "dist_R")


def _decisive(record: dict) -> bool:
    """docs/aggregation.md's rule, written out: a car closer than 20 m ahead in a neighbouring lane, either system."""
    return any(record[name] < 20.0 for name in DECISIVE)


def test_emphasis_repeats_each_decisive_frame_and_nothing_else(data):
    ordered = FrameDataset(data, split="train", normalised=False)
    decisive = [_decisive(ordered.record(i)[1]) for i in range(len(ordered))]
    assert 0 < sum(decisive) < len(decisive)   # the fixture's traffic gives both kinds
    where = ("x", "y", "s")   # a frame's place names it (targets repeat while a car stands)
    stream = FrameStream(data, split="train", normalised=False, shuffle=False, emphasis=3, context=where)
    assert len(stream) == len(ordered) + 2 * sum(decisive)
    places = [tuple(c.numpy()) for *_, c in stream]
    assert len(places) == len(stream)
    counts: dict = {}
    for p in places:
        counts[p] = counts.get(p, 0) + 1
    for i in range(len(ordered)):
        record = ordered.record(i)[1]
        assert counts[tuple(record[n] for n in where)] == (3 if decisive[i] else 1), i
    assert stream.batches(16) == len(stream) // 16


def test_emphasis_needs_a_world_that_declares_decisive_steps(data, monkeypatch):
    from dataclasses import replace

    from core import worlds
    monkeypatch.setitem(worlds._REGISTERED, "highway", replace(HIGHWAY, decisive=()))
    with pytest.raises(DatasetError, match="declares no decisive steps"):
        FrameStream(data, split="train", emphasis=2)
    assert len(FrameStream(data, split="train")) == 160   # weight 1 reads no rule
