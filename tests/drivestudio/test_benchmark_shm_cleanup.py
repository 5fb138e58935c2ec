"""`benchmark --shm` killed leaves nothing behind that outlives the next benchmark: the segments of a run whose whole
process group was killed (nobody left to remove them) are reclaimed when the next one starts, and a SIGTERM'd run
ends in one line with status 143, leaving no segment and no driver statistics file in the temporary folder."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.helpers import driven_frames

BENCH = [sys.executable, "-m", "drivestudio", "benchmark", "--model", "oracle", "--shm", "--workers", "1", "--clips",
         "0"]


def _segments_of(pids: set[int]) -> list[str]:
    """drivestudio benchmark segments (drivestudio-PID-bN) made by a worker among `pids`."""
    return [n for n in os.listdir("/dev/shm") if n.startswith("drivestudio-") and "-b" in n
            and int(n.split("-")[1]) in pids]


def _descendants(pid: int) -> set[int]:
    out, todo = set(), [pid]
    while todo:
        p = todo.pop()
        kids = subprocess.run(["ps", "-o", "pid=", "--ppid", str(p)], capture_output=True, text=True).stdout.split()
        out.update(map(int, kids))
        todo += map(int, kids)
    return out


def _start(suite: Path, out: Path, tmp: Path) -> tuple[subprocess.Popen, list[str]]:
    proc = subprocess.Popen(BENCH + ["--suite", str(suite), "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, "TMPDIR": str(tmp)})
    t0 = time.time()
    while time.time() - t0 < 120:
        names = _segments_of(_descendants(proc.pid))
        if names and any(driven_frames(n) >= 10 for n in names):   # the route is being driven
            return proc, names
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.1)
    os.killpg(proc.pid, signal.SIGKILL)
    raise AssertionError("the benchmark did not start driving")


@pytest.mark.long
def test_killed_and_terminated_benchmarks_leave_nothing_behind(tmp_path):
    suite = tmp_path / "suite.json"
    suite.write_text(json.dumps({"name": "long", "description": "one long route", "routes": [
        {"name": "r1", "track": "oval", "lanes": 2, "cars": 0, "seed": 1, "seconds": 3600}]}))
    tmp = tmp_path / "tmp"
    tmp.mkdir()

    first, left = _start(suite, tmp_path / "first", tmp)
    os.killpg(first.pid, signal.SIGKILL)          # the whole process group: world, worker and driver
    first.wait()
    time.sleep(0.5)
    assert all(os.path.exists(f"/dev/shm/{n}") for n in left)   # nobody was left to remove them

    second, running = _start(suite, tmp_path / "second", tmp)
    try:
        assert not any(os.path.exists(f"/dev/shm/{n}") for n in left)   # reclaimed as the next one started
        second.send_signal(signal.SIGTERM)
        _, err = second.communicate(timeout=120)
    finally:
        if second.poll() is None:   # the test failed on its way: leave nothing running or mapped
            os.killpg(second.pid, signal.SIGKILL)
            second.wait()
            for n in left + running:
                Path(f"/dev/shm/{n}").unlink(missing_ok=True)
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("benchmark: suite")]
    assert second.returncode == 143 and lines == ["drivestudio benchmark: terminated by SIGTERM"], err
    time.sleep(0.5)
    assert not any(os.path.exists(f"/dev/shm/{n}") for n in running)
    assert sorted(p.name for p in tmp.iterdir()) == []   # no driver statistics file, nothing else
