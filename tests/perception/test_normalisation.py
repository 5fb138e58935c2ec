"""Targets are normalised to about [0.1, 0.9] with the highway declaration's maps (DeepDriving's) and mapped back
at prediction time."""
import numpy as np
import pytest
import torch

from core.worlds.highway import HIGHWAY, INACTIVE, INDICATORS, NORMALISATION, label_set
from perception.models import build
from tests.perception.frames import dataset

normalise, denormalise = HIGHWAY.normalise, HIGHWAY.denormalise


def test_label_sets_are_13_14_15():
    assert label_set() == INDICATORS[:13]
    assert label_set(fast=True) == INDICATORS
    assert label_set(fast=True, lanes_left=True) == INDICATORS + ("lanes_left",)
    assert label_set(lanes_left=True)[-1] == "lanes_left" and len(label_set(lanes_left=True)) == 14


def test_round_trip_through_the_declaration_is_exact_in_range():
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


def test_the_model_wrapper_denormalises_with_the_declaration():
    labels = label_set(fast=True)
    model = build("gist", HIGHWAY, labels)
    out = torch.rand(5, len(labels))
    np.testing.assert_allclose(model.denormalise(out), denormalise(out.numpy(), labels), rtol=1e-6)
    assert model.spec["normalisation"] == {n: list(NORMALISATION[n]) for n in labels}


def test_dataset_targets_are_the_normalised_labels():
    from perception.datasets import FrameDataset

    raw = FrameDataset(dataset(), "train", label_set(lanes_left=True), normalised=False)
    norm = FrameDataset(dataset(), "train", label_set(lanes_left=True), normalised=True)
    for i in (0, len(raw) // 2, len(raw) - 1):
        image, _, target = norm[i]
        assert image.dtype == torch.uint8 and image.shape == (3, 210, 280)
        assert 0.0 <= float(target.min()) and float(target.max()) <= 1.0
        np.testing.assert_allclose(denormalise(target.numpy(), norm.targets)[1:], raw[i][2].numpy()[1:], atol=1e-4)


def test_the_declaration_holds_deepdrivings_maps_exactly():
    """Every affine map of DeepDriving's Euclidean loss layer, label by label (docs/affordances.md)."""
    expected = {"angle": (1 / 1.1, 0.5), "toMarking_L": (0.17778, 1.34445), "toMarking_M": (0.14545, 0.39091),
                "toMarking_R": (0.17778, -0.34445), "toMarking_LL": (0.14545, 1.48181), "toMarking_ML": (0.16, 0.98),
                "toMarking_MR": (0.16, 0.02), "toMarking_RR": (0.14545, -0.48181), "fast": (0.6, 0.2),
                "lanes_left": (0.2, 0.1), **{g: (1 / 95, 0.12) for g in ("dist_LL", "dist_MM", "dist_RR", "dist_L",
                                                                         "dist_R")}}
    for name, (scale, offset) in expected.items():
        label = HIGHWAY.label(name)
        assert (label.scale, label.offset) == pytest.approx((scale, offset)), name
    assert HIGHWAY.label("angle").clip == (0.0, 1.0) and HIGHWAY.label("dist_MM").clip is None
