"""The checkpoint format: one torch file holding plain data only, loaded with `weights_only=True` (no pickled
code runs), written atomically (a temporary file renamed into place, so a crash leaves the previous one; a
temporary left by a killed save is removed by the next save to the same place).

    format, version   "drivestudio-perception", 2 (version 1, from before worlds were declared, is refused)
    spec              the model (perception/models.py): family, world, labels and outputs, options, input,
                      normalisation
    state_dict        the model's tensors
    state_sha256      SHA-256 of the tensors (names, dtypes, shapes, bytes), checked at load: a byte flipped inside
                      a tensor is refused (absent from checkpoints written before it existed, which still load)
    train             progress and settings: config (JSON-able), iteration, epoch, step_in_epoch, history
    optimizer, scheduler, rng    what resuming needs (absent from fitted GIST models)
    data              the training data's manifest summary: root, frames per split, manifest fields
"""
from __future__ import annotations

import hashlib
import pickle
import warnings
from pathlib import Path

import torch

from core.files import atomic_write
from core.signals import deferred
from core.worlds.highway import PAPER_INDICATORS

FORMAT = "drivestudio-perception"
VERSION = 2


class CheckpointError(ValueError):
    """A checkpoint (or weights file) that cannot be used: missing, not ours, truncated, or not the model asked for."""


DIGEST = "state_sha256"


def save_checkpoint(path, payload: dict) -> None:
    """Write atomically, with the digest of the weights; a SIGTERM or Ctrl-C during the write takes effect once it
    is complete."""
    if isinstance(payload.get("state_dict"), dict):
        payload = {**payload, DIGEST: tensor_digest(payload["state_dict"])}
    with deferred():
        atomic_write(path, lambda f: torch.save({"format": FORMAT, "version": VERSION, **payload}, f))


def tensor_digest(state: dict) -> str:
    """SHA-256 over a state dict's tensors in name order: each name, dtype and shape, then its bytes."""
    h = hashlib.sha256()
    for key in sorted(state):
        t = state[key]
        if not isinstance(t, torch.Tensor):
            raise CheckpointError(f"the weights hold a {type(t).__name__} under '{key}', not a tensor")
        t = t.detach().cpu().contiguous()
        h.update(f"{key}\0{t.dtype}\0{tuple(t.shape)}\0".encode())
        h.update(t.reshape(-1).view(torch.uint8).numpy().tobytes())
    return h.hexdigest()


def check_weights(path, ckpt: dict) -> None:
    """Refuse weights that are not the ones saved (their digest differs) or that are not finite (a diverged or
    damaged model would drive, or be exported, with NaN outputs)."""
    state = ckpt["state_dict"]
    try:
        digest = tensor_digest(state)
    except CheckpointError as e:
        raise CheckpointError(f"{path} is damaged: {e}") from None
    stored = ckpt.get(DIGEST)
    if stored is not None and stored != digest:
        raise CheckpointError(f"{path} is damaged: its weights are not the ones that were saved (the SHA-256 of "
                              "its tensors differs from the one stored with them)")
    for key, t in state.items():
        if t.is_floating_point() and not bool(torch.isfinite(t).all()):
            raise CheckpointError(f"{path} holds weights that are not finite (NaN or infinity in '{key}'): a "
                                  "diverged or damaged model is refused")


def load_checkpoint(path, model: str | None = None, labels=None, map_location="cpu", world: str | None = None) -> dict:
    """Read and check a checkpoint; `model`, `labels` and `world`, when given, must be the ones it was trained
    for."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"no checkpoint at {path}")
    with path.open("rb") as f:
        is_archive = f.read(4) == b"PK\x03\x04"  # torch.save's zip format
    try:
        # mmap: tensors are read when used, so a predictor does not read a training checkpoint's optimiser state
        with warnings.catch_warnings():   # a file of another kind may read as an odd pickle: our line says it
            warnings.filterwarnings("ignore", message="Detected pickle protocol", category=UserWarning)
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
    if ckpt.get("version") == 1:
        raise CheckpointError(f"{path} is a checkpoint of format version 1 (drivestudio 0.1), which is no longer "
                              "read; train it again")
    if ckpt.get("version") != VERSION:
        raise CheckpointError(f"{path} has checkpoint version {ckpt.get('version')}; this reader reads version "
                              f"{VERSION}")
    spec = ckpt.get("spec")
    if not isinstance(spec, dict) or not isinstance(ckpt.get("state_dict"), dict) or \
            not {"name", "world", "labels", "outputs", "input", "normalisation"} <= set(spec):
        raise CheckpointError(f"{path} is a drivestudio checkpoint without a model in it")
    check_weights(path, ckpt)
    if world is not None and spec["world"] != world:
        raise CheckpointError(f"{path} is a model of the {spec['world']} world, not of the {world} world")
    if model is not None and spec["name"] != model:
        raise CheckpointError(f"{path} holds a '{spec['name']}' model, not '{model}'")
    if labels is not None and tuple(spec["labels"]) != tuple(labels):
        raise CheckpointError(f"{path} predicts {describe_labels(spec['labels'])}, not the "
                              f"{describe_labels(labels)} asked for (--targets must match)")
    return ckpt


def describe_labels(labels) -> str:
    """"13 indicators (the paper's)", "14 indicators (the paper's 13 + fast)", ..."""
    labels = tuple(labels)
    extra = [n for n in labels[13:]]
    if labels[:13] == PAPER_INDICATORS:
        return f"{len(labels)} indicators (the paper's 13{''.join(' + ' + n for n in extra)})"
    return f"{len(labels)} labels ({', '.join(labels)})"
