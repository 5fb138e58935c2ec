"""core/allocator.py: with freed memory kept, a large block freed and allocated again reuses its pages (no minor
page faults after the first time); without, the kernel maps and zeroes it anew each time. Trainings whose steps
repeat run with it."""
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


class Steps:
    """A trainer of two steps (the protocol of perception/trainer.py) that notes whether freed memory was kept when
    its steps ran."""
    reads: frozenset = frozenset()

    def __init__(self, repeats: bool, kept: list):
        self.repeats, self.kept, self.seen = repeats, kept, []

    def plan(self):
        from perception.trainer import Plan
        return Plan(steps=2, validate_every=2)

    def restore(self):
        return iter([(1, None), (2, None)])

    def step(self, work) -> bool:
        self.seen.append(bool(self.kept))
        return False

    def validate(self) -> None:
        pass

    def save(self, occasion) -> dict:
        return {}


@pytest.mark.parametrize("repeats", [True, False])
def test_a_training_keeps_freed_memory_only_when_its_steps_repeat_their_allocations(monkeypatch, repeats):
    """SGD iterations and MultiNet's epochs allocate the same blocks again and again and keep freed memory; GIST's
    one pass keeps its descriptors as it goes and does not (kept results split freed blocks, the heap grows)."""
    import perception.train as train
    from perception.gist_fit import GistTrainer
    from perception.multinet import MultiNetTrainer
    from perception.train_sgd import SGDTrainer
    assert SGDTrainer.repeats and MultiNetTrainer.repeats and not GistTrainer.repeats
    kept: list = []
    monkeypatch.setattr(train, "keep_freed_memory", lambda: kept.append(True))
    trainer = Steps(repeats, kept)
    train.run(trainer)
    assert trainer.seen == [repeats, repeats]
