"""Writing results so that a crash or Ctrl-C never leaves a half-written file behind, and nothing that is not a
regular file is ever replaced (core/files.py owns the rules)."""
from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np

from core.files import atomic_write, check_output, reclaim_temporaries
from drivestudio.errors import UsageError


def write_png(path, rgb: np.ndarray) -> None:
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise UsageError(f"could not encode {path} as PNG")
    atomic_write(Path(path), buf.tobytes())


def write_json(path, obj) -> None:
    atomic_write(Path(path), (json.dumps(obj, indent=2) + "\n").encode())


def write_text(path, text: str) -> None:
    atomic_write(Path(path), text.encode())


class VideoWriter:
    """An MPEG-4 (mp4v) video of RGB frames, written to a hidden file and renamed into place on close()."""

    def __init__(self, path, fps: float = 10.0):
        self.path = check_output(path, (".mp4",), "video")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        reclaim_temporaries(self.path.parent, self.path.name)
        self._tmp = self.path.parent / f".{self.path.name}.{os.getpid()}.0.tmp.mp4"
        self.fps = fps
        self._writer: cv2.VideoWriter | None = None
        self.frames = 0

    def write(self, rgb: np.ndarray) -> None:
        if self._writer is None:
            h, w = rgb.shape[:2]
            self._writer = cv2.VideoWriter(str(self._tmp), cv2.VideoWriter.fourcc(*"mp4v"), self.fps, (w, h))
            if not self._writer.isOpened():
                raise UsageError(f"cannot write video {self.path} (no MPEG-4 encoder in this OpenCV)")
        self._writer.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        self.frames += 1

    def close(self) -> None:
        if self._writer is not None:
            self._writer.release()
            self._writer = None
            data = self._tmp.read_bytes()
            self._tmp.unlink(missing_ok=True)
            atomic_write(self.path, data)

    def abort(self) -> None:
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        self._tmp.unlink(missing_ok=True)
