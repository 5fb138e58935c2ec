"""core/allocator.py: with freed memory kept, a large block freed and allocated again reuses its pages (no minor
page faults after the first time); without, the kernel maps and zeroes it anew each time. Every verb runs with it."""
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

STEPS = """
import ctypes, resource, sys
from core.allocator import keep_freed_memory
if sys.argv[1] == "keep":
    assert keep_freed_memory()
libc = ctypes.CDLL(None)
libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, (ctypes.c_size_t,)
libc.free.argtypes = (ctypes.c_void_p,)
n = 64 << 20                       # an activation of a training step: above glibc's largest mmap threshold
def step():
    p = libc.malloc(n)
    ctypes.memset(p, 1, n)
    libc.free(p)
step()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(5):
    step()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def faults(mode: str) -> int:
    done = subprocess.run([sys.executable, "-c", STEPS, mode], capture_output=True, text=True, cwd=REPO, timeout=60)
    assert done.returncode == 0, done.stderr
    return int(done.stdout)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_a_freed_block_is_reused_without_page_faults():
    kept, plain = faults("keep"), faults("plain")
    assert kept < 50                  # the same pages, already mapped
    assert plain > 10 * max(kept, 1)  # 16,384 a step with 4 KB pages


def test_every_verb_keeps_freed_memory(monkeypatch):
    import drivestudio.cli as cli
    called = []
    monkeypatch.setattr(cli, "keep_freed_memory", lambda: called.append(True))
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    assert called == [True]
