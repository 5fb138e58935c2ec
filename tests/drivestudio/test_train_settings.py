"""`drivestudio train`'s command line is derived from perception/train_config.py's TrainConfig: the settings most
runs give are flags, every other one is `--set NAME=VALUE`, listed with its default; a setting given reaches the
trainer; a bad value, an unknown name, or a setting the family's trainer does not read is one line and exit status 2
before any work; and --help stays short."""
from __future__ import annotations

import csv
from pathlib import Path

import pytest

from bench.count_options import counts
from core.settings import entries
from drivestudio.cli import main
from drivestudio.commands import train as train_command
from drivestudio.commands.run_settings import default_text
from perception.train_config import TrainConfig

REPO = Path(__file__).resolve().parents[2]
SMALL = str(REPO / "tests" / "dataset" / "fixtures" / "highway-10")


def test_train_help_shows_at_most_15_options():
    assert counts("highway")["train"] <= 15


def test_the_set_help_lists_every_other_setting_with_the_configurations_default(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "120")
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    shown = set(train_command.REQUIRED + train_command.FLAGS)
    for name, e in entries(TrainConfig).items():
        if name not in shown:
            assert f"{name}={default_text(e.default)}" in help_text, name
    assert "lr_step=1000," in help_text and "checkpoint_every=300.0 s," in help_text
    assert "--workers WORKERS processes decoding frames, 0-64 (default 1)" in help_text


def test_a_set_setting_reaches_the_trainer(tmp_path, capsys):
    """The learning rate halves every 2 iterations and the curve has a row per iteration: lr_step, lr_gamma and
    log_every given with --set are the ones the SGD trainer ran with, and the checkpoint records them."""
    from perception.checkpoint import load_checkpoint
    out = tmp_path / "m.pt"
    assert main(["train", "--data", SMALL, "--model", "alexnet", "--out", str(out), "--iterations", "4",
                 "--batch-size", "2", "--lr", "0.01", "--workers", "0", "--device", "cpu", "--set", "lr_step=2",
                 "--set", "lr_gamma=0.5", "--set", "log_every=1", "--set", "optimizer=adam"]) == 0
    with open(f"{out}.loss.csv") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["iteration"]) for r in rows] == [1, 2, 3, 4]
    assert [float(r["lr"]) for r in rows] == pytest.approx([0.01, 0.005, 0.005, 0.0025])
    config = load_checkpoint(out)["train"]["config"]
    assert (config["lr_step"], config["lr_gamma"], config["optimizer"]) == (2, 0.5, "adam")


@pytest.mark.parametrize("extra, words", [
    (["--set", "lr_step=0"], "--set lr_step must be an integer from 1 to 1e+08, got 0"),
    (["--set", "lr_step=often"], "--set lr_step must be an integer, got 'often'"),
    (["--set", "loss=l3"], "--set loss: invalid choice: 'l3' (choose from euclidean, l1)"),
    (["--set", "ema=1.5"], "--set ema must be a number from 0 to 0.9999, got 1.5"),
    (["--set", "lr-step=5"], "--set lr-step: no such setting"),
    (["--set", "lr_step"], "--set takes NAME=VALUE, got 'lr_step'"),
    (["--lr", "0"], "--lr must be a number from 1e-09 to 100, got 0.0"),
    (["--set", "steer_share=0.5"], "steer_share does not apply to --model alexnet (its sgd training reads "
                                   "iterations, epochs, batch_size"),
])
def test_a_bad_setting_is_one_line_and_status_2_before_any_work(tmp_path, capsys, extra, words):
    rc = main(["train", "--data", SMALL, "--model", "alexnet", "--out", str(tmp_path / "m.pt"), *extra])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and words in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("flag", ["--lr-step", "--no-amp", "--val-every", "--history", "--emphasis", "--mtl"])
def test_the_settings_without_a_flag_of_their_own_are_not_flags(tmp_path, capsys, flag):
    with pytest.raises(SystemExit) as exited:
        main(["train", "--data", SMALL, "--model", "alexnet", "--out", str(tmp_path / "m.pt"), flag, "1"])
    assert exited.value.code == 2 and "unrecognized arguments" in capsys.readouterr().err
