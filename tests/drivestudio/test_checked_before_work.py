"""Options are checked before any work: an option or setting that would be ignored is refused, a combination that
cannot be honoured is refused, and every model of a run is opened before the first is used (docs/errors.md). Each
case: one line on stderr, exit status 2, nothing written."""
from __future__ import annotations

from pathlib import Path

import pytest
import torch

from core.settings import SettingError
from core.worlds.highway import HIGHWAY
from core.worlds.sidewalk import SIDEWALK
from drivestudio.cli import main
from perception.checkpoint import save_checkpoint
from perception.models import Regressor, make_spec
from perception.train_config import TrainConfig

REPO = Path(__file__).resolve().parents[2]
SMALL = str(REPO / "tests" / "dataset" / "fixtures" / "highway-10")


def _refused(capsys, argv: list[str], words: str) -> None:
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and words in err, err


@pytest.mark.parametrize("extra, words", [
    (["--model", "z2color", "--iterations", "5"], "iterations does not apply to --model z2color"),
    (["--model", "z2color", "--weights", "vgg16.pth"], "weights does not apply to --model z2color"),
    (["--model", "z2color", "--workers", "3"], "workers does not apply to --model z2color"),
    (["--model", "z2color", "--set", "momentum=0.5"], "momentum does not apply to --model z2color"),
    (["--model", "gist", "--init", "model.pt"], "init does not apply to --model gist"),
    (["--model", "gist", "--lr", "0.1", "--epochs", "2"], "epochs, lr do not apply to --model gist"),
    (["--model", "gist", "--set", "cache=false"], "cache does not apply to --model gist"),
    (["--model", "alexnet", "--set", "trials=3"], "trials does not apply to --model alexnet"),
    (["--model", "alexnet", "--set", "mode_moments=500"], "mode_moments does not apply to --model alexnet"),
    (["--model", "alexnet", "--set", "unfreeze=true"], "unfreeze does not apply to --model alexnet"),
    (["--model", "alexnet", "--set", "history=1"], "history does not apply to --model alexnet"),
    (["--model", "z2color", "--set", "modes=,"], "modes ',' names no mode"),
    (["--model", "z2color", "--set", "modes="], "modes '' names no mode"),
])
def test_train_refuses_settings_its_trainer_would_ignore(tmp_path, capsys, extra, words):
    _refused(capsys, ["train", "--data", SMALL, "--out", str(tmp_path / "m.pt"), *extra], words)
    assert list(tmp_path.iterdir()) == []


def test_a_refusal_names_what_the_trainer_reads():
    """One line: the setting given and every setting that family's trainer takes (perception/train.py)."""
    from perception.train import check_reads
    with pytest.raises(SettingError) as refused:
        check_reads(TrainConfig(model="gist", lr_step=5))
    assert str(refused.value) == "lr_step does not apply to --model gist (its closed-form training reads val_frames, " \
                                 "regressor)"


def test_settings_the_multinet_trainer_reads_are_accepted():
    """amp false (float32 throughout, perception/multinet.py) is read by Z2Color's trainer, so it is not refused;
    VGG-16's own settings are read for it alone, a temporal family's history for it alone."""
    from perception.train import check_reads
    check_reads(TrainConfig(model="z2color", amp=False, trials=3, mtl="direct"))
    check_reads(TrainConfig(model="vgg16", unfreeze=True, batch_norm=True))
    check_reads(TrainConfig(model="mobilenet", history=2))
    with pytest.raises(SettingError, match="amp does not apply to --model gist"):
        check_reads(TrainConfig(model="gist", amp=False))
    with pytest.raises(SettingError, match="batch_norm does not apply to --model mobilenet"):
        check_reads(TrainConfig(model="mobilenet", batch_norm=True))


def test_evaluate_refuses_models_of_two_worlds_before_evaluating_either(tmp_path, capsys):
    torch.manual_seed(0)
    for name, model in (("highway.pt", Regressor(make_spec("gist", HIGHWAY))),
                        ("sidewalk.pt", Regressor(make_spec("z2color", SIDEWALK)))):
        save_checkpoint(tmp_path / name, {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    out = tmp_path / "report"
    _refused(capsys, ["evaluate", "--data", SMALL, "--model", str(tmp_path / "highway.pt"), "--model",
                      str(tmp_path / "sidewalk.pt"), "--out", str(out)],
             "sidewalk.pt is a model of the sidewalk world, not of the highway world")
    assert not out.exists()


def test_train_opens_the_first_of_several_data_folders_for_its_checks(tmp_path, capsys):
    """Z2Color trains on a data set and the corrections of later rounds (--data A,B): the check of the --init
    checkpoint's world reads the first folder instead of refusing the list as no dataset."""
    torch.manual_seed(0)
    model = Regressor(make_spec("z2color", SIDEWALK))
    save_checkpoint(tmp_path / "sidewalk.pt", {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    _refused(capsys, ["train", "--data", f"{SMALL},{SMALL}", "--model", "z2color", "--out", str(tmp_path / "m.pt"),
                      "--init", str(tmp_path / "sidewalk.pt"), "--batch-size", "60"],
             "sidewalk.pt is a model of the sidewalk world, not of the highway world")
    assert not (tmp_path / "m.pt").exists()


@pytest.mark.parametrize("extra, words", [
    (["--out", "{tmp}/pngs", "--video", "{tmp}/v.mp4"], "--out FOLDER (PNGs) and --video FILE.mp4"),
    (["--video", "{tmp}/v.mp4", "--select", "worst"], "--select goes with PNGs"),
    (["--out", "{tmp}/pngs", "--episode", "3"], "--episode goes with --video"),
    (["--out", "{tmp}/pngs", "--seed", "4"], "--seed goes with --select random"),
])
def test_overlay_refuses_options_it_would_ignore(tmp_path, capsys, extra, words):
    _refused(capsys, ["overlay", "--data", SMALL, *[e.format(tmp=tmp_path) for e in extra]], words)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("verb, blocked", [
    (["train", "--data", SMALL, "--model", "gist", "--out", "{tmp}/m.pt"], "m.pt.loss.png"),
    (["evaluate", "--data", SMALL, "--model", "{tmp}/model.pt", "--out", "{tmp}"], "mae.png"),
    (["benchmark", "--model", "oracle", "--out", "{tmp}"], "leaderboard.md"),
])
def test_every_file_a_verb_will_write_is_checked_before_work(tmp_path, capsys, verb, blocked):
    """A side output that cannot be written (here: a folder stands where the file goes) is found before any work,
    not after hours of it."""
    torch.manual_seed(0)
    model = Regressor(make_spec("gist", HIGHWAY))
    save_checkpoint(tmp_path / "model.pt", {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    (tmp_path / blocked).mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    _refused(capsys, [a.format(tmp=tmp_path) for a in verb], f"{blocked}: it is a folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_batch_that_cannot_fit_in_memory_is_refused_before_allocating(tmp_path, capsys):
    _refused(capsys, ["train", "--data", SMALL, "--model", "alexnet", "--batch-size", "65536", "--out",
                      str(tmp_path / "m.pt")], "--batch-size 65536: its inputs (3 x 210 x 280 a sample) alone need")
    assert list(tmp_path.iterdir()) == []
