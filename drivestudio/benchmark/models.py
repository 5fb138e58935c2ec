"""The models a benchmark compares: `oracle` (the Chen controller on the exact indicators, the upper bound) or a
checkpoint of the highway world, optionally with the controller-side smoothing of its estimates.

    --model oracle
    --model runs/alexnet.pt
    --model runs/alexnet.pt@smoothing=0.5      e = 0.5 e_previous + 0.5 e_now before the Chen controller

Every checkpoint is opened and checked before anything is driven: a missing file, a file that is no checkpoint,
or a model of another world (a sidewalk Z2Color) is refused in one line (exit status 2).
"""
from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass
from pathlib import Path

from ..errors import UsageError

ORACLE = "oracle"
MAX_SMOOTHING = 0.95     # as drive --smoothing
OPTION = re.compile(r"([a-z_]+)=(.*)")


@dataclass(frozen=True)
class ModelSpec:
    text: str                  # as given on the command line
    path: str | None           # the checkpoint; None: the oracle
    smoothing: float = 0.0
    label: str = ORACLE        # the row's name in the leaderboard
    family: str = ORACLE       # "oracle", "alexnet", "gist", "vgg16", ...
    outputs: tuple = ()

    @property
    def key(self) -> str:
        """What identifies the row: the same checkpoint with another smoothing is another row."""
        return ORACLE if self.path is None else f"{Path(self.path).resolve()}@{self.smoothing:g}"

    @property
    def is_oracle(self) -> bool:
        return self.path is None

    def as_dict(self) -> dict:
        d = asdict(self)
        d["outputs"] = list(self.outputs)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "ModelSpec":
        return cls(**{**d, "outputs": tuple(d.get("outputs", ()))})


def _smoothing(value: str, text: str) -> float:
    try:
        a = float(value)
    except ValueError:
        a = math.nan
    if not math.isfinite(a) or not 0.0 <= a <= MAX_SMOOTHING:
        raise UsageError(f"--model {text}: smoothing must be a number from 0 to {MAX_SMOOTHING}, got {value!r}")
    return a


def parse_model(text: str) -> tuple[str, float]:
    """(checkpoint or 'oracle', smoothing) of a --model value: PATH or PATH@smoothing=A."""
    if not text.strip():
        raise UsageError("--model: empty; give 'oracle' or a checkpoint file")
    path, smoothing = text, 0.0
    head, at, tail = text.rpartition("@")
    if at and not Path(text).is_file():   # a file whose name holds '@' is still a file
        path = head
        for part in tail.split(","):
            m = OPTION.fullmatch(part.strip())
            if m is None or m[1] != "smoothing":
                raise UsageError(f"--model {text}: after '@' the options are smoothing=A (0 to {MAX_SMOOTHING}), "
                                 f"got {part!r}")
            smoothing = _smoothing(m[2], text)
    if path == ORACLE and smoothing:
        raise UsageError(f"--model {text}: the oracle reads the exact indicators; smoothing applies to checkpoints")
    return path, smoothing


def check_model(text: str) -> ModelSpec:
    """The model of a --model value, its checkpoint opened and checked (a model of the highway world)."""
    path, smoothing = parse_model(text)
    if path == ORACLE:
        return ModelSpec(text, None)
    from perception.checkpoint import load_checkpoint
    from perception.models import check_spec, describe

    from ..commands.common import check_checkpoint_path
    check_checkpoint_path(path)
    ckpt = load_checkpoint(path, world="highway")     # CheckpointError (exit 2): not ours, or another world's
    spec = ckpt["spec"]
    check_spec(spec, path)
    label = f"{describe(spec)} ({Path(path).name})" + (f", smoothing {smoothing:g}" if smoothing else "")
    return ModelSpec(text, str(path), smoothing, label, spec["name"], tuple(spec["outputs"]))


def check_models(texts: list[str] | None) -> list[ModelSpec]:
    """The rows of a benchmark, the oracle first (added when not asked for: it is the upper bound every other row
    is compared with); a model given twice is refused."""
    models = [check_model(t) for t in (texts or [ORACLE])]
    seen: dict[str, str] = {}
    for m in models:
        if m.key in seen:
            raise UsageError(f"--model {m.text} is the same model as --model {seen[m.key]}; give each once")
        seen[m.key] = m.text
    oracle = [m for m in models if m.is_oracle] or [ModelSpec(ORACLE, None)]
    return oracle + [m for m in models if not m.is_oracle]


def slug(model: ModelSpec, taken: set[str]) -> str:
    """A file-name-safe short name of the model, unique among `taken` (clip folders)."""
    if model.is_oracle:
        base = ORACLE
    else:
        base = re.sub(r"[^A-Za-z0-9_.+-]+", "-", Path(model.path).stem).strip("-.") or "model"
        if model.smoothing:
            base += f"-smoothing{model.smoothing:g}"
    name, i = base, 2
    while name in taken:
        name, i = f"{base}-{i}", i + 1
    taken.add(name)
    return name
