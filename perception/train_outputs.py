"""Every file a training writes, so that each is checked before any work (docs/errors.md): the checkpoint, its loss
curves beside it (`<out>.loss.csv`, `.loss.png`) and, for Z2Color's trainer, the state of an unfinished run
(`<out>.state`). A folder, a device or an unwritable place at any of them is refused in one line before the data is
read, rather than after an epoch when the checkpoint is already written."""
from __future__ import annotations

from pathlib import Path

from core.files import check_output
from perception.curves import curve_paths

CHECKPOINT_SUFFIXES = (".pt", ".pth", ".ckpt")


def state_path(out) -> Path:
    """Where Z2Color's trainer keeps an unfinished run (perception/multinet.py), beside the checkpoint."""
    out = Path(out)
    return out.with_name(out.name + ".state")


def side_outputs(out, trainer: str) -> list[tuple[Path, str]]:
    """(path, what it is) of every file a trainer ("sgd", "closed-form", "multinet") writes beside `out`."""
    csv_path, png_path = curve_paths(out)
    files = [(csv_path, "loss-curve file"), (png_path, "loss-curve picture")]
    if trainer == "multinet":
        files.append((state_path(out), "training state"))
    return files


def check_train_outputs(out, trainer: str) -> None:
    """OutputError (one line) unless the checkpoint and every side output of the trainer can be written."""
    check_output(out, CHECKPOINT_SUFFIXES, "checkpoint")
    for path, what in side_outputs(out, trainer):
        check_output(path, None, what)
