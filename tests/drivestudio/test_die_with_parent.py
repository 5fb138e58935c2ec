"""No process outlives the verb that started it: after kill -9, SIGTERM or SIGINT of the verb's own process (not its
group), every descendant recorded before the signal is gone within a few seconds, and the next run starts clean (no
shared-memory segment of the killed run is left). Real processes throughout; descendants are read from /proc."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from core.processes import pid_alive

REPO = Path(__file__).resolve().parents[2]
DS = [sys.executable, "-m", "drivestudio"]
GONE_WITHIN = 5.0   # [s]
STATUS = {signal.SIGKILL: -signal.SIGKILL, signal.SIGTERM: 143, signal.SIGINT: 130}


def descendants(pid: int) -> set[int]:
    """Every live process below `pid`, from the parent links in /proc."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as f:
                data = f.read()
        except OSError:
            continue
        ppid = int(data[data.rfind(b")") + 2:].split()[1])
        children.setdefault(ppid, []).append(int(entry))
    out, todo = set(), [pid]
    while todo:
        for kid in children.get(todo.pop(), []):
            if kid not in out:
                out.add(kid)
                todo.append(kid)
    return {p for p in out if pid_alive(p)}


def segments() -> set[str]:
    return {n for n in os.listdir("/dev/shm") if n.startswith("drivestudio-")}


def command_line(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


class Started:
    """A process started in its own session (so that the test's signals reach it alone, and the test can always
    clean up after itself), with the descendants it has once `ready(descendants)` holds."""

    def __init__(self, argv: list[str], ready, tmp: Path, timeout: float = 120.0, **kw):
        self.proc = subprocess.Popen(argv, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                     start_new_session=True, env={**os.environ, "TMPDIR": str(tmp)}, **kw)
        t0 = time.time()
        while time.time() - t0 < timeout:
            self.kids = descendants(self.proc.pid)
            if ready(self.kids):
                return
            if self.proc.poll() is not None:
                raise AssertionError(f"exited with {self.proc.returncode} before it was ready: "
                                     f"{self.proc.stderr.read() if self.proc.stderr else ''}")
            time.sleep(0.1)
        self.cleanup()
        raise AssertionError(f"not ready within {timeout:g} s: {argv}")

    def signal_and_check(self, signum: int) -> None:
        """Send `signum` to the process alone; every descendant recorded before must be gone soon after."""
        os.kill(self.proc.pid, signum)
        try:
            rc = self.proc.wait(timeout=60)
            deadline = time.time() + GONE_WITHIN
            while time.time() < deadline and any(pid_alive(p) for p in self.kids):
                time.sleep(0.1)
            left = {p: command_line(p) for p in self.kids if pid_alive(p)}
            assert not left, f"left running after {signal.Signals(signum).name}: {left}"
            assert rc == STATUS[signum], (rc, self.proc.stderr.read() if self.proc.stderr else "")
        finally:
            self.cleanup()

    def cleanup(self) -> None:
        for p in self.kids | descendants(self.proc.pid):
            try:
                os.kill(p, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        if self.proc.stderr:
            self.proc.stderr.close()


def _cmdlines(pids) -> list[str]:
    return [command_line(p) for p in pids]


# --- the helper itself ------------------------------------------------------------------------------------------------
PARENT = """
import multiprocessing, sys, time
from core.children import popen, worker_initializer
popen(["sleep", "60"])
popen([sys.executable, "-c", "import time; from core.children import popen; popen(['sleep', '61']); time.sleep(60)"])
pool = multiprocessing.get_context("fork").Pool(2, initializer=worker_initializer)
pool.map_async(time.sleep, [62, 62])
time.sleep(60)
"""


def test_children_grandchildren_and_pool_workers_die_with_a_killed_parent(tmp_path):
    def ready(kids) -> bool:   # two sleeps (one a grandchild), the middle python and the pool's two workers
        lines = _cmdlines(kids)
        return sum("sleep 6" in ln for ln in lines) == 2 and len(kids) >= 5

    started = Started([sys.executable, "-c", PARENT], ready, tmp_path, timeout=30)
    started.signal_and_check(signal.SIGKILL)


# --- the verbs ----------------------------------------------------------------------------------------------------
def _suite(tmp_path: Path) -> Path:
    suite = tmp_path / "suite.json"
    suite.write_text(json.dumps({"name": "long", "description": "one long route", "routes": [
        {"name": "r1", "track": "oval", "lanes": 2, "cars": 0, "seed": 1, "seconds": 3600}]}))
    return suite


def _owned(names: set[str], pids: set[int]) -> set[str]:
    """The segments named after one of `pids` (`drivestudio-PID[-suffix]`): a test running beside this one on
    another worker makes segments of its own."""
    return {n for n in names if int(n.split("-")[1]) in pids}


def _driving(kids) -> bool:
    """A world serves a segment and its driver process (`drive --shm`) is among the descendants."""
    return any("drive --shm" in ln for ln in _cmdlines(kids)) and bool(segments())


@pytest.mark.parametrize("signum", [pytest.param(signal.SIGKILL, marks=pytest.mark.long), signal.SIGTERM,
                                    pytest.param(signal.SIGINT, marks=pytest.mark.long)])
def test_benchmark_shm_leaves_no_process_behind_and_a_rerun_starts_clean(tmp_path, signum):
    suite = _suite(tmp_path)
    argv = DS + ["benchmark", "--model", "oracle", "--shm", "--workers", "1", "--clips", "0", "--suite",
                 str(suite)]
    before = segments()
    first = Started(argv + ["--out", str(tmp_path / "first")], lambda k: _driving(k) and segments() - before,
                    tmp_path)
    left = _owned(segments() - before, {first.proc.pid} | first.kids)
    assert left
    first.signal_and_check(signum)
    if signum != signal.SIGKILL:
        assert not segments() & left   # removed by the run itself
        return
    rerun = Started(argv + ["--out", str(tmp_path / "rerun")], lambda k: _driving(k) and segments() - before - left,
                    tmp_path)
    assert not segments() & left   # the killed run's segments, reclaimed as the next one started
    rerun.signal_and_check(signal.SIGTERM)


@pytest.mark.parametrize("signum", [signal.SIGKILL, signal.SIGTERM, signal.SIGINT])
def test_drive_over_the_bridge_leaves_no_driver_behind(tmp_path, signum):
    argv = DS + ["drive", "--model", "oracle", "--cars", "0", "--seconds", "3600"]
    first = Started(argv + ["--out", str(tmp_path / "first")], _driving, tmp_path)
    name = f"drivestudio-{first.proc.pid}"
    first.signal_and_check(signum)
    if signum != signal.SIGKILL:
        assert name not in segments()
        return
    rerun = Started(argv + ["--out", str(tmp_path / "rerun")], lambda k: _driving(k) and name not in segments(),
                    tmp_path)
    rerun.signal_and_check(signal.SIGTERM)


def test_generate_leaves_no_worker_behind(tmp_path):
    def ready(kids) -> bool:
        return sum("drivestudio.pool worker" in ln for ln in _cmdlines(kids)) == 2

    started = Started(DS + ["generate", "--out", str(tmp_path / "data"), "--frames", "100000", "--cars", "0",
                            "--workers", "2"], ready, tmp_path)
    started.signal_and_check(signal.SIGKILL)


SIDE_BY_SIDE = """
import sys
from pathlib import Path
from drivestudio.commands.recipe_steps import run_side_by_side
out = Path(sys.argv[1])
run_side_by_side([["serve", "--shm", "drivestudio-sbs-" + out.name, "--cars", "0", "--wait", "120"]],
                 [out / "serve.log"])
"""

STUDY_JOBS = """
import sys
from pathlib import Path
from drivestudio.worlds.sidewalk.study import Job, run_jobs
run_jobs([Job("a", ["60"]), Job("b", ["61"])], 2, Path(sys.argv[1]), command=("sleep",))
"""


@pytest.mark.parametrize("script, ready", [
    (SIDE_BY_SIDE, lambda kids: any("serve --shm" in ln for ln in _cmdlines(kids))),
    (STUDY_JOBS, lambda kids: sum(ln.startswith("sleep 6") for ln in _cmdlines(kids)) == 2),
], ids=["recipe-side-by-side", "study-jobs"])
def test_the_trainings_of_recipe_and_study_die_with_their_parent(tmp_path, script, ready):
    try:
        started = Started([sys.executable, "-c", script, str(tmp_path)], ready, tmp_path)
        started.signal_and_check(signal.SIGKILL)
    finally:   # a killed serve's segment, left for the next run to reclaim: this test's own, removed here
        Path("/dev/shm", f"drivestudio-sbs-{tmp_path.name}").unlink(missing_ok=True)
