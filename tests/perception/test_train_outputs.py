"""Every file a training writes (the checkpoint, its loss curves, Z2Color's state of an unfinished run) is checked
before any work, by every trainer and every verb that trains: a folder in the place of one is refused in one line
with status 2, and nothing is written (docs/errors.md)."""
from __future__ import annotations

from pathlib import Path

import pytest
import torch

from core.files import OutputError
from core.worlds.sidewalk import SIDEWALK
from drivestudio.cli import main
from perception.checkpoint import save_checkpoint
from perception.models import Regressor, make_spec
from perception.train_outputs import side_outputs

SMALL = str(Path(__file__).resolve().parents[1] / "dataset" / "fixtures" / "highway-10")
SIDES = [".loss.csv", ".loss.png", ".state"]


def _quiet(*args, **kwargs) -> None:
    pass


def _tree(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.fixture(scope="module")
def sidewalk_data(tmp_path_factory):
    """Six episodes of 20 steps: two of each mode, so that a retraining can hold one of each out."""
    out = tmp_path_factory.mktemp("outputs") / "data"
    assert main(["generate", "--world", "sidewalk", "--frames", "120", "--episode-frames", "20",
                 "--set", "stereo.width=168", "--set", "stereo.height=94", "--paths", "park", "--workers", "1",
                 "--seed", "5", "--out", str(out)]) == 0
    return out


def test_each_trainer_names_its_side_outputs(tmp_path):
    out = tmp_path / "m.pt"
    assert [p.name for p, _ in side_outputs(out, "sgd")] == ["m.pt.loss.csv", "m.pt.loss.png"]
    assert [p.name for p, _ in side_outputs(out, "multinet")] == ["m.pt.loss.csv", "m.pt.loss.png", "m.pt.state"]


@pytest.mark.parametrize("side", SIDES)
def test_train_refuses_a_folder_at_a_multinet_side_output(sidewalk_data, tmp_path, capsys, side):
    (tmp_path / f"m.pt{side}").mkdir()
    rc = main(["train", "--data", str(sidewalk_data), "--model", "z2color", "--epochs", "1", "--batch-size", "6",
               "--out", str(tmp_path / "m.pt")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and f"m.pt{side}: it is a folder" in err, (rc, err)
    assert _tree(tmp_path) == [f"m.pt{side}"]


@pytest.mark.parametrize("model, data, side", [("z2color", "SIDEWALK", ".loss.png"), ("z2color", "SIDEWALK", ".state"),
                                               ("gist", SMALL, ".loss.csv"), ("gist", SMALL, ".loss.png")])
def test_the_trainer_called_as_a_library_checks_them_before_any_work(sidewalk_data, tmp_path, model, data, side):
    from perception.train import train
    from perception.training import config_from
    (tmp_path / f"m.pt{side}").mkdir()
    cfg = config_from(data=str(sidewalk_data) if data == "SIDEWALK" else data, model=model,
                      out=str(tmp_path / "m.pt"), epochs=1, batch_size=6, val_frames=20)
    with pytest.raises(OutputError, match="it is a folder"):
        train(cfg, log=_quiet)
    assert _tree(tmp_path) == [f"m.pt{side}"]


@pytest.mark.parametrize("side", SIDES)
def test_autonomy_checks_the_side_outputs_of_its_retrainings_before_round_0(sidewalk_data, tmp_path, capsys, side):
    torch.manual_seed(0)
    model = Regressor(make_spec("z2color", SIDEWALK))
    ckpt = tmp_path / "net.pt"
    save_checkpoint(ckpt, {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    out = tmp_path / "run"
    (out / f"model-round1.pt{side}").mkdir(parents=True)
    rc = main(["autonomy", "--model", str(ckpt), "--set", f"data={sidewalk_data}", "--mode", "direct", "--seconds",
               "1", "--rounds", "2", "--set", "epochs=1", "--set", "video=false", "--device", "cpu", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and f"model-round1.pt{side}: it is a folder" in err, (rc, err)
    assert _tree(out) == [f"model-round1.pt{side}"]


def test_study_checks_every_training_output_before_recording_data(tmp_path, capsys):
    out = tmp_path / "study"
    (out / "models" / "multinet-round1.pt.loss.png").mkdir(parents=True)
    rc = main(["study", "--out", str(out), "--quick", "--set", "rounds=1"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "multinet-round1.pt.loss.png: it is a folder" in err, (rc, err)
    assert _tree(out) == ["models", "models/multinet-round1.pt.loss.png"]
