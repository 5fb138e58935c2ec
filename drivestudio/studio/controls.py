"""Pause, single step and pace, set from the pages (the server's thread) and obeyed by the loop (its thread).

Every message a page may send that changes the run goes through `Controls.put` into one queue; the loop's thread
takes them between steps (`drain`) and, while paused, waits on the queue (`hold`), so that the world and the
driver are only ever touched by the loop's thread. Pause, resume and step are handled here; the others by the
caller's `handle`.
"""
from __future__ import annotations

import queue
import time
from collections.abc import Callable

from core.signals import check as check_signals
from drivestudio.studio.protocol import Message

HOLD_POLL = 0.1     # [s] a paused loop looks at the signals and re-publishes its step this often


class Controls:
    def __init__(self, paused: bool = False, realtime: bool = True):
        self.queue: queue.SimpleQueue[Message] = queue.SimpleQueue()
        self.paused, self.realtime = paused, realtime
        self._steps = 0          # single steps granted while paused
        self.changed = True      # something the pages show changed (cleared by the publisher)

    def put(self, msg: Message) -> None:
        self.queue.put(msg)

    def _apply(self, msg: Message, handle: Callable[[Message], None]) -> None:
        self.changed = True
        if msg.type == "pause":
            self.paused = True
        elif msg.type == "resume":
            self.paused, self._steps = False, 0
        elif msg.type == "step":
            self.paused = True
            self._steps += 1
        elif msg.type == "pace":
            self.realtime = bool(msg.fields["realtime"])
        else:
            handle(msg)

    def drain(self, handle: Callable[[Message], None]) -> None:
        """Apply every queued message (loop thread, between steps)."""
        while True:
            try:
                msg = self.queue.get_nowait()
            except queue.Empty:
                return
            self._apply(msg, handle)

    def hold(self, handle: Callable[[Message], None], idle: Callable[[], None] | None = None) -> bool:
        """While paused, wait for messages (idle() runs every HOLD_POLL seconds meanwhile); returns when running
        again or when a single step is granted. Returns whether it waited."""
        self.drain(handle)
        waited = False
        while self.paused and self._steps == 0:
            waited = True
            check_signals()
            if idle is not None:
                idle()
            try:
                msg = self.queue.get(timeout=HOLD_POLL)
            except queue.Empty:
                continue
            self._apply(msg, handle)
        if self._steps:
            self._steps -= 1
        return waited


class Pacer:
    """Real-time pacing of a loop whose pace can change and that can pause: step n is released at
    origin + n dt, and the origin starts again after a pause or a change of pace."""

    def __init__(self, dt: float):
        self.dt = dt
        self.restart()

    def restart(self) -> None:
        self._origin, self._n = time.perf_counter(), 0

    def wait(self) -> None:
        self._n += 1
        ahead = self._origin + self._n * self.dt - time.perf_counter()
        if ahead > 0:
            time.sleep(ahead)
        elif ahead < -0.5:   # far behind (a slow step, a checkpoint loading): do not rush to catch up
            self.restart()
