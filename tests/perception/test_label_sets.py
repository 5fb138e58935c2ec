"""Named label sets (`train --targets paper|extended`): the extended labels reach datasets and models through the
declaration alone. `--targets` takes a set, labels in place of the default, or +labels added to it."""
import numpy as np
import pytest

from core.worlds.highway import HIGHWAY, LABEL_SETS, PAPER_INDICATORS, REAR
from drivestudio.cli import main
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


def test_targets_name_a_label_set_as_labels_did():
    assert resolve_targets(HIGHWAY, "extended") == resolve_targets(HIGHWAY, None, label_set="extended") == EXTENDED
    assert resolve_targets(HIGHWAY, "paper") == PAPER_INDICATORS
    assert resolve_targets(HIGHWAY, "extended,+dist_LB") == EXTENDED   # a set's own label added once
    with pytest.raises(TrainingError, match="no label wide .labels: angle, .*; label sets: paper, extended."):
        resolve_targets(HIGHWAY, "wide")


def test_targets_add_the_labels_fast_and_lanes_left_added():
    with_both = resolve_targets(HIGHWAY, "+fast,+lanes_left")
    assert with_both == resolve_targets(HIGHWAY, None, extra=("fast", "lanes_left"))
    assert with_both == PAPER_INDICATORS + ("fast", "lanes_left")
    assert resolve_targets(HIGHWAY, "+fast") == PAPER_INDICATORS + ("fast",)
    assert resolve_targets(HIGHWAY, "angle,dist_MM") == ("angle", "dist_MM")
    with pytest.raises(TrainingError, match="not names and .names"):
        resolve_targets(HIGHWAY, "angle,+fast")


def test_a_generated_dataset_carries_the_rear_labels_and_a_model_learns_the_extended_set():
    frames = FrameDataset(dataset(), "train", targets=EXTENDED)
    _, _, target = frames[0]
    assert len(target) == len(EXTENDED) and np.isfinite(np.asarray(target)).all()
    out = workdir() / "gist-extended.pt"
    train(tiny_config("gist", out, labels="extended"), log=lambda *a: None)
    spec = load_checkpoint(out)["spec"]
    assert tuple(spec["labels"]) == EXTENDED and tuple(spec["outputs"])[-4:] == REAR
    assert spec["normalisation"]["dist_LB"] == [pytest.approx(0.8 / 100), 0.1]


def test_train_targets_extended_learns_the_extended_set(capsys):
    out = workdir() / "gist-targets-extended.pt"
    assert main(["train", "--data", str(dataset()), "--model", "gist", "--out", str(out), "--targets", "extended"]) == 0
    assert tuple(load_checkpoint(out)["spec"]["labels"]) == EXTENDED


def test_an_unknown_label_set_is_refused_in_one_line_before_any_work(capsys, tmp_path):
    out = tmp_path / "m.pt"
    assert main(["train", "--data", str(dataset()), "--model", "gist", "--out", str(out), "--targets", "wide"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no label wide" in err and "label sets: paper, extended" in err
    assert not out.exists()


@pytest.mark.parametrize("flag", ["--labels", "--fast", "--lanes-left"])
def test_the_flags_targets_replaced_are_gone(capsys, tmp_path, flag):
    with pytest.raises(SystemExit) as exited:
        main(["train", "--data", str(dataset()), "--model", "gist", "--out", str(tmp_path / "m.pt"), flag])
    assert exited.value.code == 2 and "unrecognized arguments" in capsys.readouterr().err
