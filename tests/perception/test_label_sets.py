"""Named label sets (`train --labels paper|extended`): the extended labels reach datasets and models through the
declaration alone."""
import numpy as np
import pytest

from core.worlds.highway import HIGHWAY, LABEL_SETS, PAPER_INDICATORS, REAR
from perception.checkpoint import load_checkpoint
from perception.datasets import FrameDataset
from perception.train import train
from perception.training import TrainingError, resolve_targets
from tests.perception.frames import dataset, tiny_config, workdir

EXTENDED = PAPER_INDICATORS + ("fast", "lanes_left", "dist_LB", "dist_RB", "closing_LB", "closing_RB")


def test_label_sets_name_the_default_targets():
    assert resolve_targets(HIGHWAY, None) == resolve_targets(HIGHWAY, None, label_set="paper") == PAPER_INDICATORS
    assert resolve_targets(HIGHWAY, None, label_set="extended") == EXTENDED == LABEL_SETS["extended"]
    assert resolve_targets(HIGHWAY, "+lanes_left", label_set="paper") == PAPER_INDICATORS + ("lanes_left",)
    with pytest.raises(TrainingError, match="no label set 'wide' .label sets: paper, extended."):
        resolve_targets(HIGHWAY, None, label_set="wide")
    with pytest.raises(TrainingError, match="--targets may only add"):
        resolve_targets(HIGHWAY, "angle", label_set="extended")


def test_a_generated_dataset_carries_the_rear_labels_and_a_model_learns_the_extended_set():
    frames = FrameDataset(dataset(), "train", targets=EXTENDED)
    _, _, target = frames[0]
    assert len(target) == len(EXTENDED) and np.isfinite(np.asarray(target)).all()
    out = workdir() / "gist-extended.pt"
    train(tiny_config("gist", out, labels="extended"), log=lambda *a: None)
    spec = load_checkpoint(out)["spec"]
    assert tuple(spec["labels"]) == EXTENDED and tuple(spec["outputs"])[-4:] == REAR
    assert spec["normalisation"]["dist_LB"] == [pytest.approx(0.8 / 100), 0.1]


def test_an_unknown_label_set_is_refused_in_one_line_before_any_work(run_cli, tmp_path):
    out = tmp_path / "m.pt"
    r = run_cli("train", "--data", dataset(), "--model", "gist", "--out", out, "--labels", "wide")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "no label set 'wide'" in r.stderr
    assert not out.exists()
