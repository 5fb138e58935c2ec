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


class VideoWriter:
    """An MPEG-4 (mp4v) video of RGB frames, written to a hidden file and renamed into place on close()."""

    def __init__(self, path, fps: float = 10.0):
        self.path = Path(path)
        if self.path.suffix.lower() != ".mp4":
            raise UsageError(f"videos are written as .mp4, got {self.path.name}")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self.path.parent / f".{self.path.stem}.{os.getpid()}.tmp.mp4"
        self.fps = fps
        self._writer = None
        self.frames = 0

    def write(self, rgb: np.ndarray) -> None:
        if self._writer is None:
            h, w = rgb.shape[:2]
            self._writer = cv2.VideoWriter(str(self._tmp), cv2.VideoWriter_fourcc(*"mp4v"), self.fps, (w, h))
            if not self._writer.isOpened():
                raise UsageError(f"cannot write video {self.path} (no MPEG-4 encoder in this OpenCV)")
        self._writer.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        self.frames += 1

    def close(self) -> None:
        if self._writer is not None:
            self._writer.release()
            self._writer = None
            os.replace(self._tmp, self.path)

    def abort(self) -> None:
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        self._tmp.unlink(missing_ok=True)
