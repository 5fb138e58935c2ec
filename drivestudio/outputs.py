"""Writing results so that a crash or Ctrl-C never leaves a half-written file behind."""
from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np

from .errors import UsageError


def _atomic(path: Path, data: bytes) -> None:
    path = Path(path)
    if path.parent and not path.parent.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.parent / f".{path.name}.{os.getpid()}.tmp"
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_png(path, rgb: np.ndarray) -> None:
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise UsageError(f"could not encode {path} as PNG")
    _atomic(Path(path), buf.tobytes())


def write_json(path, obj) -> None:
    _atomic(Path(path), (json.dumps(obj, indent=2) + "\n").encode())


def write_text(path, text: str) -> None:
    _atomic(Path(path), text.encode())
