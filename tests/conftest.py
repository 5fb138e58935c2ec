"""What every test shares."""
import functools
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers import run_main

# A shell starts a background job (`pytest &`, `nohup pytest`) with SIGINT ignored, and an ignored signal stays
# ignored in every process started from it: the tests that stop a verb with SIGINT (exit status 130) would wait in
# vain. Python's own handler here lets the verbs they start begin with SIGINT at its default, as from a terminal.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def share_the_cores(config) -> None:
    """pytest's workers (-n N) split the cores between them: each worker, and every command it starts, computes on
    cores / N threads (OMP_NUM_THREADS, inherited by the workers started after this), unless the caller set it. With
    torch's default of a thread per core each, two workers on two cores run four threads, which wait on each other:
    the suite takes about 10 % longer and 15 % more CPU time (docs/log.md)."""
    workers = getattr(config.option, "numprocesses", None)
    cores = len(os.sched_getaffinity(0))
    if workers == "auto" or workers == "logical":
        workers = cores
    if isinstance(workers, int) and workers > 1 and "OMP_NUM_THREADS" not in os.environ:
        os.environ["OMP_NUM_THREADS"] = str(max(1, cores // workers))


def pytest_configure(config):
    """The default renderer's kernels and the stereo renderer's compile once (about 30 and 15 s on a fresh clone, then
    numba's cache), here in the process that starts pytest's workers, before any of them renders; side by side, since
    numba compiles on one thread."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        share_the_cores(config)
        from sim.highway.kernels import compile_numba_kernels
        stereo = subprocess.Popen([sys.executable, "-c", "from sim.sidewalk.kernels import compile_stereo_kernels as "
                                   "c; c()"], cwd=Path(__file__).resolve().parents[1])
        compile_numba_kernels()
        if stereo.wait() != 0:
            raise pytest.UsageError("the stereo renderer's kernels did not compile (see above)")


@pytest.fixture
def run_cli(capfd):
    """`run_cli("render", "-o", path, cwd=..., env=...)`: the command in this process (tests/helpers.py), returning
    its exit status and what it wrote on stdout and stderr."""
    return functools.partial(run_main, capfd)


@pytest.fixture(scope="session", autouse=True)
def _folder_the_workers_share(tmp_path_factory):
    """Under pytest -n, a folder all workers of the run see (their base temporary folders' parent), for data one
    worker makes and the others reuse (tests/perception/frames.py); pytest removes it with the run's others."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        os.environ["DRIVESTUDIO_TEST_SHARED"] = str(tmp_path_factory.getbasetemp().parent)
