"""Run several `drivestudio` commands at once as child processes, one thread each, with their progress on one line.

The recipe trains an ensemble's members this way: on a machine with fewer cores than members, one thread per
training is what keeps the cores busy without the trainings' thread pools fighting (two trainings side by side on
2 cores take 1.4x one training's time, not 2x: docs/aggregation.md). Each child writes its own log; the progress
line reads the last `N/M` count each log shows. A child that fails stops the others, and its log's last line is
the error this run reports.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

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


def run_side_by_side(commands: list[list[str]], logs: list[Path], every: float = 60.0) -> None:
    """Run `drivestudio ARGV` for each of `commands` at once, stdout and stderr into the matching log; returns when
    all have succeeded, raises RunError naming the first that failed (the others are stopped)."""
    env = os.environ | ONE_THREAD
    procs = []
    t0 = time.perf_counter()
    try:
        for argv, log in zip(commands, logs):
            with open(log, "ab") as out:
                procs.append(subprocess.Popen([sys.executable, "-m", "drivestudio", *argv], stdout=out,
                                              stderr=subprocess.STDOUT, env=env))
        shown = t0
        while [p.poll() for p in procs].count(None):   # every child polled: any() would stop at the first running
            failed = [(p, log) for p, log in zip(procs, logs) if p.returncode not in (None, 0)]
            if failed:
                p, log = failed[0]
                raise RunError(f"{log.name}: exit status {p.returncode}: {last_line(log)}")
            if time.perf_counter() - shown >= every:
                shown = time.perf_counter()
                print(f"  {(shown - t0) / 60:5.1f} min: " + ", ".join(progress(log) for log in logs), flush=True)
            time.sleep(1.0)
        for p, log in zip(procs, logs):
            if p.returncode != 0:
                raise RunError(f"{log.name}: exit status {p.returncode}: {last_line(log)}")
    finally:
        for p in procs:
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
