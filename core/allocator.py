"""The C allocator kept from handing freed memory back to the kernel.

glibc's malloc serves every block above a threshold (at most 32 MB) by mmap and unmaps it when it is freed, and
hands the heap's free top back once it passes the trim threshold. A training step allocates the same large
activations every iteration, so each iteration the kernel maps them anew and zeroes every page on first touch:
a minor page fault for each 4 KB. `recipe --extended` took 297 million of them (622 s of system time in 96 minutes
of CPU). Serving every block from the heap and keeping what is freed lets the next step reuse the same pages: the
recipe's MobileNet, three trainings side by side on two cores, trains 1.16x as fast with a third of the page faults
(docs/benchmarks.md). A process's memory then stays at its peak until it ends, and a process that keeps small
results between large temporaries of changing sizes (GIST's descriptors of frames, a batch at a time) can split
freed blocks until the heap grows by a block a batch: so only trainings whose steps repeat the same allocations
keep freed memory (perception/train.py).
"""
from __future__ import annotations

import ctypes
import sys

M_TRIM_THRESHOLD = -1    # glibc's malloc.h
M_MMAP_MAX = -4
TRIM_THRESHOLD = 1 << 30  # hand back a free top of the heap only past 1 GB


def keep_freed_memory() -> bool:
    """Blocks from the heap, not mmap, and the heap's top kept; True where the C library is glibc's."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt     # the C library the process runs on
    except (OSError, AttributeError):           # not glibc (musl has no mallopt)
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(M_MMAP_MAX, 0)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
