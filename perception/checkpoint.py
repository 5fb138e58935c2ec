"""The checkpoint format: one torch file holding plain data only, loaded with `weights_only=True` (no pickled
code runs), written atomically (a temporary file renamed into place, so a crash leaves the previous one).

    format, version   "drivestudio-perception", 1
    spec              the model (perception/models.py): name, labels, options, input statistics, normalisation
    state_dict        the model's tensors
    train             progress and settings: config (JSON-able), iteration, epoch, step_in_epoch, history
    optimizer, scheduler, rng    what resuming needs (absent from fitted GIST models)
    data              the training data's manifest summary: root, frames per split, manifest fields
"""
from __future__ import annotations

import os
import pickle
import tempfile
from pathlib import Path

import torch

FORMAT = "drivestudio-perception"
VERSION = 1


class CheckpointError(ValueError):
    """A checkpoint (or weights file) that cannot be used: missing, not ours, truncated, or not the model asked for."""


def _replace_atomically(path, write) -> None:
    """Call write(file) on a hidden temporary file beside `path`, then rename it into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # the permissions of an ordinary new file, not mkstemp's 0600
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write(path, data: bytes) -> None:
    _replace_atomically(path, lambda f: f.write(data))


def save_checkpoint(path, payload: dict) -> None:
    _replace_atomically(path, lambda f: torch.save({"format": FORMAT, "version": VERSION, **payload}, f))


def load_checkpoint(path, model: str | None = None, labels=None, map_location="cpu") -> dict:
    """Read and check a checkpoint; `model` and `labels`, when given, must be the ones it was trained for."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"no checkpoint at {path}")
    with path.open("rb") as f:
        is_archive = f.read(4) == b"PK\x03\x04"  # torch.save's zip format
    try:
        # mmap: tensors are read when used, so a predictor does not read a training checkpoint's optimiser state
        ckpt = torch.load(path, map_location=map_location, weights_only=True, mmap=is_archive)
    except pickle.UnpicklingError:  # pickled code (refused by weights_only), or a file of another kind
        raise CheckpointError(f"{path} is not a drivestudio checkpoint (it holds pickled objects or is no "
                              "torch file)") from None
    except Exception as e:
        if is_archive:
            raise CheckpointError(f"{path} is truncated or corrupt (an incomplete torch archive)") from None
        raise CheckpointError(f"{path} is not a drivestudio checkpoint ({type(e).__name__})") from None
    if not isinstance(ckpt, dict) or ckpt.get("format") != FORMAT:
        raise CheckpointError(f"{path} is not a drivestudio checkpoint")
    if ckpt.get("version") != VERSION:
        raise CheckpointError(f"{path} has checkpoint version {ckpt.get('version')}; this reader reads {VERSION}")
    spec = ckpt.get("spec")
    if not isinstance(spec, dict) or not isinstance(ckpt.get("state_dict"), dict) or \
            not {"name", "labels", "input", "normalisation"} <= set(spec):
        raise CheckpointError(f"{path} is a drivestudio checkpoint without a model in it")
    if model is not None and spec["name"] != model:
        raise CheckpointError(f"{path} holds a '{spec['name']}' model, not '{model}'")
    if labels is not None and tuple(spec["labels"]) != tuple(labels):
        raise CheckpointError(f"{path} predicts {describe_labels(spec['labels'])}, not the "
                              f"{describe_labels(labels)} asked for (--fast / --lanes-left must match)")
    return ckpt


def describe_labels(labels) -> str:
    """"13 indicators (the paper's)", "14 indicators (the paper's 13 + fast)", ..."""
    labels = tuple(labels)
    extra = [n for n in labels[13:]]
    from shm_bridge.vocabulary import PAPER_INDICATORS
    if labels[:13] == PAPER_INDICATORS:
        return f"{len(labels)} indicators (the paper's 13{''.join(' + ' + n for n in extra)})"
    return f"{len(labels)} outputs ({', '.join(labels)})"


def load_model(path, model: str | None = None, labels=None, device="cpu"):
    """The model of a checkpoint, in eval mode on `device`: (Regressor, checkpoint dict)."""
    from .models import Regressor, check_normalisation

    ckpt = load_checkpoint(path, model=model, labels=labels)
    check_normalisation(ckpt["spec"], str(path))
    net = Regressor(ckpt["spec"])
    try:
        net.load_state_dict(ckpt["state_dict"])
    except RuntimeError as e:
        raise CheckpointError(f"{path}: the weights do not fit its {ckpt['spec']['name']} model "
                              f"({str(e).splitlines()[0]})") from None
    return net.to(device).eval(), ckpt
