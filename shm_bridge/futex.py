"""Linux futexes on 32-bit words inside a shared mapping, through ctypes (no compiled code).

The operations are the non-private FUTEX_WAIT / FUTEX_WAKE, because the two sides are unrelated processes that
map the same file. The ctypes call releases the GIL, so other threads (the heartbeat) run while a thread sleeps.
"""
from __future__ import annotations

import ctypes
import errno
import os
import platform

FUTEX_WAIT = 0
FUTEX_WAKE = 1
_INT_MAX = 0x7FFFFFFF

# syscall numbers of futex(2) per architecture (x86-64: 202)
_SYS_FUTEX = {"x86_64": 202, "amd64": 202, "aarch64": 98, "arm64": 98, "i386": 240, "i686": 240,
              "armv7l": 240, "ppc64le": 221, "riscv64": 98, "s390x": 238}


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


def _load():
    number = _SYS_FUTEX.get(platform.machine().lower())
    if number is None:
        return None, None
    libc = ctypes.CDLL(None, use_errno=True)
    fn = libc.syscall
    fn.restype = ctypes.c_long
    fn.argtypes = [ctypes.c_long, ctypes.c_void_p, ctypes.c_int, ctypes.c_uint, ctypes.c_void_p,
                   ctypes.c_void_p, ctypes.c_uint]
    return number, fn


SYS_FUTEX, _syscall = _load()


def available() -> bool:
    return _syscall is not None


def _require() -> None:
    if _syscall is None:
        raise OSError(errno.ENOSYS, f"futex syscall number unknown on {platform.machine()} (Linux only)")


def wait(address: int, expected: int, timeout: float | None) -> bool:
    """Sleep while the uint32 at `address` equals `expected`, at most `timeout` seconds (None: no limit).

    Returns False when the timeout expired, True otherwise (woken, the word already differed, or a signal
    arrived: Python then runs its handler, e.g. raises KeyboardInterrupt, when this call returns).
    """
    _require()
    if timeout is None:
        ts_ptr = None
    else:
        timeout = max(0.0, timeout)
        sec = int(timeout)
        ts = _Timespec(sec, int((timeout - sec) * 1e9))
        ts_ptr = ctypes.addressof(ts)
    r = _syscall(SYS_FUTEX, address, FUTEX_WAIT, expected & 0xFFFFFFFF, ts_ptr, None, 0)
    if r == 0:
        return True
    err = ctypes.get_errno()
    if err == errno.ETIMEDOUT:
        return False
    if err in (errno.EAGAIN, errno.EINTR):
        return True
    raise OSError(err, f"futex wait: {os.strerror(err)}")


def wake(address: int, count: int = _INT_MAX) -> int:
    """Wake up to `count` sleepers on the uint32 at `address`; the number woken."""
    _require()
    r = _syscall(SYS_FUTEX, address, FUTEX_WAKE, count, None, None, 0)
    if r < 0:
        err = ctypes.get_errno()
        raise OSError(err, f"futex wake: {os.strerror(err)}")
    return int(r)
