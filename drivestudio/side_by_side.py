"""Run several `drivestudio` commands at once as child processes, one thread each, with their progress on one line.

The recipe trains an ensemble's members this way: on a machine with fewer cores than members, one thread per
training is what keeps the cores busy without the trainings' thread pools fighting (two trainings side by side on
2 cores take 1.4x one training's time, not 2x: docs/aggregation.md). Each child writes its own log; the progress
line reads the last `N/M` count each log shows. A child that fails stops the others, and its log's last line is
the error this run reports. A child may wait for an earlier one to succeed: a recipe starts each aggregation round
as soon as the training it continues is done.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

from core.children import popen
from core.signals import exit_on_sigterm
from drivestudio.errors import RunError

# a child that leaves the other cores to its siblings (also the benchmark's route workers)
ONE_THREAD = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
_COUNT = re.compile(rb"(\d+)/(\d+) \[")


def progress(log: Path) -> str:
    """The last `done/total` a tqdm bar wrote to `log` ('-' before the first)."""
    try:
        with open(log, "rb") as f:
            f.seek(max(0, f.seek(0, os.SEEK_END) - 4096))
            found = _COUNT.findall(f.read())
    except OSError:
        return "-"
    return f"{int(found[-1][0])}/{int(found[-1][1])}" if found else "-"


def last_line(log: Path) -> str:
    try:
        lines = [ln.strip() for ln in log.read_text(errors="replace").replace("\r", "\n").splitlines() if ln.strip()]
    except OSError:
        return ""
    return lines[-1] if lines else ""


def run_side_by_side(commands: list[list[str]], logs: list[Path], every: float = 60.0,
                     after: list[int | None] | None = None) -> None:
    """Run `drivestudio ARGV` for each of `commands` at once, stdout and stderr into the matching log, but for a
    command i with `after[i]` (an earlier command's index), which starts when that one has succeeded; returns when
    all have succeeded, raises RunError naming the first that failed (the others are stopped). SIGTERM stops them
    all too. A child's results do not depend on what runs beside it (one thread each)."""
    n = len(commands)
    after = after or [None] * n
    if len(logs) != n or len(after) != n or any(a is not None and not 0 <= a < i for i, a in enumerate(after)):
        raise ValueError("one log per command, and each command after an earlier one")
    env = os.environ | ONE_THREAD
    procs: dict[int, subprocess.Popen] = {}
    t0 = shown = time.perf_counter()

    def start(i: int) -> subprocess.Popen:
        with open(logs[i], "ab") as out:
            return popen([sys.executable, "-m", "drivestudio", *commands[i]], stdout=out, stderr=subprocess.STDOUT,
                         env=env)

    try:
        with exit_on_sigterm():   # a recipe stopped by SIGTERM stops its children (the finally below)
            while True:
                codes = {i: p.poll() for i, p in procs.items()}   # every child polled
                failed = sorted(i for i, rc in codes.items() if rc not in (None, 0))
                if failed:
                    i = failed[0]
                    raise RunError(f"{logs[i].name}: exit status {codes[i]}: {last_line(logs[i])}")
                done = {i for i, rc in codes.items() if rc == 0}
                if len(done) == n:
                    return
                for i in range(n):
                    if i not in procs and (after[i] is None or after[i] in done):
                        procs[i] = start(i)
                if time.perf_counter() - shown >= every:
                    shown = time.perf_counter()
                    print(f"  {(shown - t0) / 60:5.1f} min: " + ", ".join(
                        progress(log) if i in procs else "waiting" for i, log in enumerate(logs)), flush=True)
                time.sleep(1.0)
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.terminate()
        for p in procs.values():
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
