"""A model checkpoint as the application opens it: the device it runs on and its predictor, refused in one line
(exit status 2) when the file is missing or the device is not here. Worlds and verbs both use it, so it lives
below drivestudio/commands/."""
from __future__ import annotations

import functools
import re
from pathlib import Path
from typing import TYPE_CHECKING

from drivestudio.errors import UsageError

if TYPE_CHECKING:
    from perception.predictor import Predictor


DEVICE = re.compile(r"(auto|cpu|cuda|cuda:\d{1,2}|mps)")   # the torch devices a verb takes


def check_device(name: str) -> str:
    """The device name, or UsageError when it is not one of DEVICE or names a GPU this machine does not have."""
    if not isinstance(name, str) or not DEVICE.fullmatch(name):
        raise UsageError(f"--device must be cpu, cuda, cuda:N or auto, got {name!r}")
    if name.startswith("cuda") or name == "mps":
        import torch  # lazy: torch takes seconds to import, and most verbs never need a GPU check
        if name.startswith("cuda") and not torch.cuda.is_available():
            raise UsageError(f"--device {name}: no CUDA device is available here")
        if name.startswith("cuda:") and int(name[5:]) >= torch.cuda.device_count():
            raise UsageError(f"--device {name}: this machine has {torch.cuda.device_count()} CUDA device(s)")
        if name == "mps" and not torch.backends.mps.is_available():
            raise UsageError("--device mps: no Apple GPU is available here")
    return name


def check_checkpoint_path(model: str, drivers: tuple[str, ...] = ()) -> Path:
    """The checkpoint file `model` names; `drivers` are the other drivers the option takes (a world's own), named in
    the message: none where only a checkpoint will do (aggregate, export, autonomy)."""
    path = Path(model)
    if not path.is_file():
        what = f"a world's driver ({', '.join(drivers)}) or a checkpoint file" if drivers else "a checkpoint file"
        raise UsageError(f"--model must be {what}; no such file: {model}")
    return path


def check_checkpoint(model: str, world: str | None, drivers: tuple[str, ...] = ()) -> dict:
    """Open a checkpoint and check it before any work starts: a model (of `world`, when given) whose weights are
    intact, finite and fit it; else one line and exit status 2 (CheckpointError). Returns its spec. `drivers`: as
    check_checkpoint_path's."""
    path = check_checkpoint_path(model, drivers)
    from perception.models import load_model  # lazy: torch
    return load_model(path, world=world)[1]["spec"]


@functools.lru_cache(maxsize=8)
def _inset(path: str, mtime_ns: int) -> str:
    from perception.models import frame_inset  # lazy: torch
    return frame_inset(check_checkpoint(path, None))


def checkpoint_inset(model: str) -> str:
    """What the frames checkpoint `model` learned held besides the scene ("", "mirror" or "mirror+sides"): the world
    that feeds it renders the same. Read once per file version; a bad file is refused in one line (exit status 2)."""
    path = check_checkpoint_path(model)
    return _inset(str(path), path.stat().st_mtime_ns)


def load_predictor_for(model: str, world: str, device: str = "cpu") -> Predictor:
    """The predictor of a checkpoint, which must be a model of `world`."""
    check_checkpoint_path(model)
    from perception.predictor import load_predictor  # lazy: torch
    return load_predictor(model, device=check_device(device), world=world)
