"""The newest step for the pages, taken from the loop at the pages' pace.

The loop calls `offer(make)` on every step; `make()` (a few references and numbers) runs only when some page is
ready for a new frame and the frame-rate cap allows one, so that a step nobody can take costs the loop a flag test.
The server's thread then draws and encodes the snapshot (`encode`) and sends it to every page that is ready: a page
has at most IN_FLIGHT frames it has not yet acknowledged, so a slow page gets fewer frames, never older ones.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from drivestudio.studio.protocol import pack_frame
from perception.shards import encode_image

JPEG_QUALITY = 80
IN_FLIGHT = 2          # frames a page may hold unacknowledged


@dataclass
class Snapshot:
    """One step as the pages will see it: the state (numbers, JSON-able) and what the view draws its images from."""

    state: dict
    view: object          # a drivestudio.studio.views view: images(capture) -> [(name, RGB)]
    capture: dict


class Publisher:
    def __init__(self, max_fps: float | None = None):
        self.min_interval = 0.0 if not max_fps else 1.0 / max_fps
        self._lock = threading.Lock()
        self._ready = False              # some page can take a frame (set by the server's thread)
        self._snapshot: Snapshot | None = None
        self._last = 0.0
        self.notify: Callable[[], object] = lambda: None   # wakes the server's thread (set by the server)
        self.published = 0

    def wants(self) -> bool:
        return self._ready and time.perf_counter() - self._last >= self.min_interval

    def offer(self, make: Callable[[], Snapshot]) -> bool:
        """Loop thread: publish the step `make()` describes if a page is ready for it. Returns whether it did."""
        if not self.wants():
            return False
        snap = make()
        with self._lock:
            self._snapshot, self._ready = snap, False
            self._last = time.perf_counter()
        self.published += 1
        self.notify()
        return True

    def ready(self) -> None:
        """Server thread: a page can take a frame."""
        self._ready = True

    def take(self) -> Snapshot | None:
        with self._lock:
            snap, self._snapshot = self._snapshot, None
        return snap


def encode(snap: Snapshot) -> bytes:
    """Draw the snapshot's images and pack the frame message (in the server's encoder thread)."""
    images = []
    for name, rgb in snap.view.images(snap.capture):     # type: ignore[attr-defined]
        if rgb is None:
            continue
        data = encode_image(rgb, "jpeg", JPEG_QUALITY)
        images.append((name, data, int(rgb.shape[1]), int(rgb.shape[0])))
    return pack_frame(snap.state, images)
