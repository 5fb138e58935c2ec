"""Bad checkpoints and mismatches fail with one clear CheckpointError line (the CLI: exit status 2)."""
import os

import pytest
import torch

from core.worlds.highway import HIGHWAY, label_set
from drivestudio.cli import main
from perception.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from perception.models import build, load_model, load_trunk
from perception.train import train
from tests.perception.frames import dataset, gist_checkpoint, tiny_config


class _Payload:
    def __reduce__(self):
        return (os.system, ("echo this must never run",))


def test_a_file_that_is_not_a_checkpoint_is_refused(tmp_path):
    (tmp_path / "notes.pt").write_text("hello")
    with pytest.raises(CheckpointError, match="not a drivestudio checkpoint"):
        load_checkpoint(tmp_path / "notes.pt")
    torch.save({"weights": torch.zeros(3)}, tmp_path / "other.pt")
    with pytest.raises(CheckpointError, match="not a drivestudio checkpoint"):
        load_checkpoint(tmp_path / "other.pt")


def test_pickled_code_is_never_run(tmp_path, capfd):
    torch.save({"format": "drivestudio-perception", "x": _Payload()}, tmp_path / "evil.pt")
    with pytest.raises(CheckpointError, match="not a drivestudio checkpoint"):
        load_checkpoint(tmp_path / "evil.pt")
    assert "must never run" not in capfd.readouterr().out


def test_a_truncated_checkpoint_is_refused(tmp_path):
    path, _ = gist_checkpoint()
    data = path.read_bytes()
    (tmp_path / "cut.pt").write_bytes(data[: len(data) // 2])
    with pytest.raises(CheckpointError, match="truncated or corrupt"):
        load_checkpoint(tmp_path / "cut.pt")


def test_a_missing_checkpoint_is_refused(tmp_path):
    with pytest.raises(CheckpointError, match="no checkpoint"):
        load_checkpoint(tmp_path / "nothing.pt")


def test_the_wrong_model_is_refused():
    path, _ = gist_checkpoint()
    with pytest.raises(CheckpointError, match="'gist' model, not 'alexnet'"):
        load_checkpoint(path, model="alexnet")
    with pytest.raises(CheckpointError, match="'gist' model, not 'alexnet'"):
        train(tiny_config("alexnet", path), log=lambda *a: None)


def test_the_wrong_indicator_set_is_refused():
    path, _ = gist_checkpoint()
    with pytest.raises(CheckpointError, match="13 indicators .* not the 14 indicators"):
        load_checkpoint(path, labels=label_set(fast=True))
    with pytest.raises(CheckpointError, match="not the 15 indicators"):
        train(tiny_config("gist", path, fast=True, lanes_left=True), log=lambda *a: None)


def test_weights_that_do_not_fit_the_model_are_refused(tmp_path):
    path, _ = gist_checkpoint()
    ckpt = torch.load(path, weights_only=True)
    ckpt["state_dict"]["net.weight"] = torch.zeros(7, 13)
    save_checkpoint(tmp_path / "bent.pt", {k: v for k, v in ckpt.items() if k not in ("format", "version")})
    with pytest.raises(CheckpointError, match="do not fit"):
        load_model(tmp_path / "bent.pt")


def test_a_different_normalisation_is_refused(tmp_path):
    path, _ = gist_checkpoint()
    ckpt = torch.load(path, weights_only=True)
    ckpt["spec"]["normalisation"]["dist_MM"] = [0.01, 0.1]
    save_checkpoint(tmp_path / "renorm.pt", {k: v for k, v in ckpt.items() if k not in ("format", "version")})
    with pytest.raises(CheckpointError, match="another normalisation of 'dist_MM'"):
        load_model(tmp_path / "renorm.pt")


def test_imagenet_weights_must_match_the_trunk(tmp_path):
    model = build("vgg16", HIGHWAY, label_set(), frozen=True)
    torch.save({"features.0.weight": torch.zeros(64, 3, 3, 3)}, tmp_path / "partial.pth")
    with pytest.raises(CheckpointError, match="not a torchvision VGG-16 ImageNet state dict"):
        load_trunk(model, tmp_path / "partial.pth")
    donor = {f"features.{k}": v + 1.0 for k, v in model.net.features.state_dict().items()}
    torch.save(donor, tmp_path / "vgg16.pth")
    assert load_trunk(model, tmp_path / "vgg16.pth") == 26
    torch.testing.assert_close(model.net.features[0].weight, donor["features.0.weight"])


def test_alexnet_takes_a_torchvision_alexnet_trunk(tmp_path):
    model = build("alexnet", HIGHWAY, label_set())
    donor = {f"features.{k}": v + 1.0 for k, v in model.net.features.state_dict().items()}
    donor["classifier.1.weight"] = torch.zeros(4096, 9216)  # torchvision's head is ignored
    torch.save(donor, tmp_path / "alexnet.pth")
    assert load_trunk(model, tmp_path / "alexnet.pth") == 10
    with pytest.raises(CheckpointError, match="not a torchvision AlexNet"):
        load_trunk(build("alexnet", HIGHWAY, label_set()), _vgg_trunk(tmp_path))


def _vgg_trunk(tmp_path):
    path = tmp_path / "vgg-like.pth"
    torch.save({"features.0.weight": torch.zeros(64, 3, 3, 3), "features.0.bias": torch.zeros(64)}, path)
    return path


def test_cli_reports_bad_checkpoints_in_one_line_with_status_2(tmp_path, capsys):
    (tmp_path / "bad.pt").write_text("not a checkpoint")
    rc = main(["evaluate", "--data", str(dataset()), "--model", str(tmp_path / "bad.pt"), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("drivestudio evaluate: error: ") and err.count("\n") == 1
    path, _ = gist_checkpoint()
    rc = main(["train", "--data", str(dataset()), "--model", "gist", "--targets", "+fast", "--out", str(path)])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("drivestudio train: error: ") and "--targets must match" in err


def test_cli_reports_a_missing_dataset_with_status_2(tmp_path, capsys):
    rc = main(["train", "--data", str(tmp_path / "nowhere"), "--model", "gist", "--out", str(tmp_path / "g.pt")])
    assert rc == 2 and "drivestudio train: error: no dataset" in capsys.readouterr().err
