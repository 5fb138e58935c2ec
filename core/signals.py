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


_deferring = [0]          # depth of deferred() blocks in progress
_pending: list[int] = []  # a signal that arrived inside one, raised when the outermost ends
_fired: list[int] = []    # the signal an exit_on_sigterm() block received, for check()


def check() -> None:
    """Raise Terminated if a signal arrived in this exit_on_sigterm() block. Call it once per step of a long loop:
    a signal handler's exception is lost when the signal lands while Python runs a finaliser or a weakref
    callback (garbage collection inside torch does this), and the loop would otherwise run on."""
    if _fired and not _deferring[0]:
        raise Terminated(_fired[0])


@contextmanager
def deferred():
    """Within the block, Terminated is held back and raised when the block ends: for work that must not be cut
    in half (writing a checkpoint). Ctrl-C is held back too."""
    _deferring[0] += 1
    previous = None
    if threading.current_thread() is threading.main_thread() and _deferring[0] == 1:
        previous = signal.signal(signal.SIGINT, lambda signum, frame: _pending.append(signum))
    try:
        yield
    finally:
        _deferring[0] -= 1
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
        if _deferring[0] == 0 and _pending:
            signum = _pending.pop(0)
            _pending.clear()
            if signum == signal.SIGINT:
                raise KeyboardInterrupt
            raise Terminated(signum)


@contextmanager
def exit_on_sigterm(signals: tuple[int, ...] = (signal.SIGTERM, signal.SIGHUP), poll: bool = False):
    """Within the block, the listed signals raise Terminated once (no-op outside the main thread); inside a
    deferred() block the signal is raised when that block ends. With poll=True the handler only notes the signal
    and the block's loop raises it by calling check(): for loops of short steps inside libraries that run
    finalisers (training), where an exception raised by the handler could be lost or cut a library call in half."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    fired = _fired
    fired.clear()

    def handler(signum, frame):
        if fired:
            return
        fired.append(signum)
        if poll:
            return
        if _deferring[0]:
            _pending.append(signum)
            return
        raise Terminated(signum)

    previous = {}
    try:
        for s in signals:
            previous[s] = signal.signal(s, handler)
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)
        fired.clear()
