"""Turn SIGTERM (and SIGHUP) into an orderly exit, so `finally` blocks and context managers run.

Python's default for SIGTERM kills the process without unwinding, which would leave /dev/shm entries behind.
Inside `exit_on_sigterm()` the first such signal raises `Terminated` (a SystemExit with status 128 + signal);
later ones are ignored while the cleanup runs. Ctrl-C already raises KeyboardInterrupt and needs no help.

    with exit_on_sigterm(), WorldEndpoint("run1") as world:
        ...
"""
from __future__ import annotations

import signal
import threading
from contextlib import contextmanager


class Terminated(SystemExit):
    """Raised in the main thread by SIGTERM/SIGHUP inside exit_on_sigterm(); code = 128 + signal number."""

    def __init__(self, signum: int):
        super().__init__(128 + signum)
        self.signum = signum

    def __str__(self) -> str:
        return f"terminated by {signal.Signals(self.signum).name}"


@contextmanager
def exit_on_sigterm(signals: tuple[int, ...] = (signal.SIGTERM, signal.SIGHUP)):
    """Within the block, the listed signals raise Terminated once (no-op outside the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    fired = []

    def handler(signum, frame):
        if fired:
            return
        fired.append(signum)
        raise Terminated(signum)

    previous = {}
    try:
        for s in signals:
            previous[s] = signal.signal(s, handler)
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)
