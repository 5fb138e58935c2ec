"""Child processes that die with their parent: the one place that says how (docs/errors.md).

Every process drivestudio starts (a generation or benchmark worker, a benchmark's driver, `drive`'s driver, the
trainings of `recipe` and `study`, a second SUMO) is started through `popen()`, and every multiprocessing worker
runs `die_with_parent()` in its initializer. Linux then sends the child SIGKILL the moment its parent ends, however
the parent ends: a SIGTERM or Ctrl-C that it handles (it stops its children in order first, then exits), or a
`kill -9` that gives it no chance to. A grandchild started the same way goes with its own parent in turn, so a
whole tree goes when its root does. What a killed child leaves (a shared-memory segment, a temporary file) is
reclaimed by the next run, as each owner of such things documents.

The kernel's request (prctl PR_SET_PDEATHSIG) is tied to the thread that started the child: when that thread
ends, so does the child. `popen()` therefore asks for it only from the main thread, which lives as long as the
process; a child started from another thread is stopped by that thread's owner as before. Elsewhere than Linux
nothing is asked and the children are stopped by their parents' cleanup only. A parent that ends its run on a
signal passes it on to a child that would otherwise wait for it (`forward()`) before waiting for the child.
"""
from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import subprocess
import threading
from collections.abc import Callable

from core.signals import Terminated

PR_SET_PDEATHSIG = 1   # <linux/prctl.h>

_prctl: list[Callable | None] = []   # libc's prctl, looked up once in the parent (never between fork and exec)


def _libc_prctl() -> Callable | None:
    if not _prctl:
        try:
            _prctl.append(ctypes.CDLL(None, use_errno=True).prctl)
        except (OSError, AttributeError):   # not Linux: no parent-death signal
            _prctl.append(None)
    return _prctl[0]


def die_with_parent(parent: int | None = None, signum: int = signal.SIGKILL) -> bool:
    """In a child: ask the kernel to send `signum` when the parent ends. With `parent` (its pid as the parent
    knew it) a child whose parent has ended already, before the request was made, ends itself at once. Returns
    whether the request was made."""
    prctl = _libc_prctl()
    if prctl is None or prctl(PR_SET_PDEATHSIG, int(signum), 0, 0, 0) != 0:
        return False
    if parent is not None and os.getppid() != parent:
        os.kill(os.getpid(), signum)
    return True


def worker_initializer(*_args) -> None:
    """For a multiprocessing Pool's `initializer` or a DataLoader's `worker_init_fn`: the worker dies with the
    process that started it."""
    parent = multiprocessing.parent_process()
    die_with_parent(parent.pid if parent is not None else os.getppid())


def popen(args, signum: int = signal.SIGKILL, **kwargs) -> subprocess.Popen:
    """subprocess.Popen whose child is sent `signum` when this process ends (from the main thread; see the
    module's note): SIGKILL by default, SIGTERM for a child that cleans up after itself (a bridge's driver removes
    the segment of a world that died). The same arguments as Popen, but for preexec_fn, which this sets."""
    if "preexec_fn" in kwargs:
        raise TypeError("popen sets preexec_fn itself")
    if threading.current_thread() is threading.main_thread() and _libc_prctl() is not None:
        parent = os.getpid()
        kwargs["preexec_fn"] = lambda: die_with_parent(parent, signum)   # between fork and exec, in the child
    return subprocess.Popen(args, **kwargs)


def forward(proc: subprocess.Popen, stopped: BaseException) -> None:
    """Pass the signal that stopped this process's run (`stopped`: KeyboardInterrupt for SIGINT, Terminated for
    SIGTERM or SIGHUP) on to a child still running, so that it ends as its parent does rather than wait for a peer
    that is gone."""
    if proc.poll() is not None:
        return
    signum = stopped.signum if isinstance(stopped, Terminated) else signal.SIGINT
    try:
        proc.send_signal(signum)
    except ProcessLookupError:   # it ended meanwhile
        pass


def end(proc: subprocess.Popen, stopped: BaseException | None, grace: float = 5.0) -> None:
    """Wait for a child to end: a run that a signal stopped passes it on first (forward). A signal that reaches a
    child while its interpreter is still starting can be lost, so after `grace` seconds it is sent SIGTERM, and
    after as long again SIGKILL."""
    if stopped is not None:
        forward(proc, stopped)
    for last_resort in (proc.terminate, proc.kill):
        try:
            proc.wait(timeout=grace)
            return
        except subprocess.TimeoutExpired:
            last_resort()
    proc.wait()
