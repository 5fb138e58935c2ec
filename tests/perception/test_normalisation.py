"""Targets are normalised to about [0.1, 0.9] with the vocabulary's maps and mapped back at prediction time."""
import numpy as np
import pytest
import torch

from perception.models import build
from shm_bridge.worlds.highway import INACTIVE, INDICATORS, NORMALISATION, denormalise, label_set, normalise

from .frames import dataset


def test_label_sets_are_13_14_15():
    assert label_set() == INDICATORS[:13]
    assert label_set(fast=True) == INDICATORS
    assert label_set(fast=True, lanes_left=True) == INDICATORS + ("lanes_left",)
    assert label_set(lanes_left=True)[-1] == "lanes_left" and len(label_set(lanes_left=True)) == 14


def test_round_trip_through_the_vocabulary_is_exact_in_range():
    labels = label_set(fast=True, lanes_left=True)
    rng = np.random.default_rng(0)
    values = np.stack([rng.uniform(-0.5, 0.5, 64)]  # angle inside its clip range
                      + [rng.uniform(-9.5, 9.5, 64) for _ in range(12)]
                      + [rng.integers(0, 2, 64).astype(float), rng.integers(0, 4, 64).astype(float)], axis=1)
    back = denormalise(normalise(values, labels), labels)
    np.testing.assert_allclose(back, values, atol=1e-4)


def test_active_and_inactive_values_land_in_about_0_1_to_0_9():
    for name, value in INACTIVE.items():
        assert 0.05 <= normalise([value], [name])[0] <= 0.95, name
    assert normalise([60.0], ["dist_MM"])[0] == pytest.approx(60 / 95 + 0.12)
    assert normalise([[0.0, 1.0]], ["fast", "fast"]).tolist() == [[pytest.approx(0.2), pytest.approx(0.8)]]


def test_angle_is_clipped_to_0_1_when_normalised():
    assert normalise([[2.0]], ["angle"])[0, 0] == 1.0
    assert normalise([[-2.0]], ["angle"])[0, 0] == 0.0


def test_the_model_wrapper_denormalises_with_the_vocabulary():
    labels = label_set(fast=True)
    model = build("gist", labels)
    out = torch.rand(5, len(labels))
    np.testing.assert_allclose(model.denormalise(out), denormalise(out.numpy(), labels), rtol=1e-6)
    assert model.spec["normalisation"] == {n: list(NORMALISATION[n]) for n in labels}


def test_dataset_targets_are_the_normalised_labels():
    from perception.datasets import FrameDataset

    raw = FrameDataset(dataset(), "train", label_set(lanes_left=True), normalised=False)
    norm = FrameDataset(dataset(), "train", label_set(lanes_left=True), normalised=True)
    for i in (0, len(raw) // 2, len(raw) - 1):
        image, target = norm[i]
        assert image.dtype == torch.uint8 and image.shape == (3, 210, 280)
        assert 0.0 <= float(target.min()) and float(target.max()) <= 1.0
        np.testing.assert_allclose(denormalise(target.numpy(), norm.labels)[1:], raw[i][1].numpy()[1:], atol=1e-4)
