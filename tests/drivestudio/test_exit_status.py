"""One meaning per exit status (docs/errors.md, "Exit statuses"): each row of the table, with the real commands.

2: the user asked for something that is refused (a name that is taken, a second driver, a segment that is not the
user's or is a symbolic link); 1: a peer died or never answered; 128 + N: ended by signal N, and then the run's
metrics are saved all the same. Every case: one line on stderr that says why, and no segment left behind.
"""
from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from core.worlds.sidewalk import SIDEWALK
from shm_bridge.endpoints import DriverEndpoint, WorldEndpoint

REPO = Path(__file__).resolve().parents[2]
DS = [sys.executable, "-m", "drivestudio"]
SERVE = DS + ["serve", "--world", "sidewalk"]


@pytest.fixture
def name():
    n = f"dsexit-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    yield n
    path = f"/dev/shm/{n}"
    leaked = os.path.lexists(path)
    if leaked:
        os.unlink(path)
    assert not leaked, f"{path} was left behind"


def _errors(stderr: str) -> list[str]:
    """The lines of stderr that are not the world's progress line."""
    return [line for line in stderr.splitlines() if "waiting for a driver" not in line and line.strip()]


def _one_line(r: subprocess.CompletedProcess, status: int, words: str) -> None:
    lines = _errors(r.stderr)
    assert r.returncode == status, r.stderr
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in r.stderr, r.stderr


# --- 2: a refusal of what the user asked for --------------------------------------------------------------------
def test_serve_with_a_name_a_live_world_holds_is_refused_with_2(name, tmp_path):
    with WorldEndpoint(name, SIDEWALK):
        r = subprocess.run(SERVE + ["--shm", name, "--out", str(tmp_path)], capture_output=True, text=True,
                           timeout=120)
        assert os.path.exists(f"/dev/shm/{name}")   # the live world's segment is untouched
    _one_line(r, 2, "in use by another world process")


def test_serve_over_a_file_that_is_not_a_segment_is_refused_with_2(name, tmp_path):
    path = Path(f"/dev/shm/{name}")
    path.write_bytes(b"not a bridge segment, keep me")
    r = subprocess.run(SERVE + ["--shm", name, "--out", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert path.read_bytes() == b"not a bridge segment, keep me"
    path.unlink()
    _one_line(r, 2, "already exists")


def test_a_second_driver_is_refused_with_2(name):
    with WorldEndpoint(name, SIDEWALK), DriverEndpoint(name, attach_timeout=1):
        r = subprocess.run(DS + ["drive", "--shm", name, "--model", "expert"], capture_output=True, text=True,
                           timeout=120)
    _one_line(r, 2, "already has a driver")


@pytest.mark.parametrize("verb", ["drive", "serve"])
def test_a_symbolic_link_in_place_of_the_segment_is_refused_with_2(name, tmp_path, verb):
    target = tmp_path / "target"
    target.write_bytes(b"keep")
    os.symlink(target, f"/dev/shm/{name}")
    args = DS + ["drive", "--shm", name] if verb == "drive" else SERVE + ["--shm", name, "--out", str(tmp_path)]
    r = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert os.path.islink(f"/dev/shm/{name}") and target.read_bytes() == b"keep"
    os.unlink(f"/dev/shm/{name}")
    _one_line(r, 2, "symbolic link")


@pytest.mark.skipif(os.geteuid() != 0, reason="giving a file to another user needs root")
def test_a_segment_of_another_user_is_refused_with_2(name):
    with WorldEndpoint(name, SIDEWALK):
        os.chown(f"/dev/shm/{name}", 65534, 65534)
        r = subprocess.run(DS + ["drive", "--shm", name], capture_output=True, text=True, timeout=120)
    _one_line(r, 2, "belongs to uid 65534")


# --- 1: a peer that died or never answered ----------------------------------------------------------------------
def test_no_driver_within_the_wait_is_1(name, tmp_path):
    r = subprocess.run(SERVE + ["--shm", name, "--wait", "1", "--out", str(tmp_path)], capture_output=True,
                       text=True, timeout=120)
    _one_line(r, 1, "no driver attached")
    assert not (tmp_path / "metrics.json").exists()   # no run took place


# (a peer that died: tests/drivestudio/test_drive.py, test_killing_the_driver_ends_the_world_within_two_seconds)

# --- 128 + N: ended by a signal, metrics saved all the same -------------------------------------------------------
DRIVER = r'''
import sys
from shm_bridge.endpoints import DriverEndpoint
with DriverEndpoint(sys.argv[1], attach_timeout=60) as ep:
    while (msg := ep.wait_frame()) is not None:
        ep.send_action(msg.seq, [0.5, 0.55])
        if msg.seq == 30:
            print("driving", flush=True)
'''


def _serve_until(name: str, out: Path, driver: bool) -> tuple[subprocess.Popen, subprocess.Popen | None]:
    serve = subprocess.Popen(SERVE + ["--shm", name, "--out", str(out)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    assert serve.stderr is not None and select.select([serve.stderr], [], [], 60)[0], "serve said nothing in 60 s"
    ready = serve.stderr.readline()     # its readiness line: the segment is there and the world waits for a driver
    assert "waiting for a driver" in ready and os.path.exists(f"/dev/shm/{name}"), ready + serve.stderr.read()
    if not driver:   # the line comes once a stop signal ends the run in order, its metrics saved
        return serve, None
    proc = subprocess.Popen([sys.executable, "-c", DRIVER, name], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None and proc.stdout.readline() == "driving\n"
    return serve, proc


@pytest.mark.parametrize("sig, status, words", [(signal.SIGINT, 130, "interrupted"),
                                               (signal.SIGTERM, 143, "terminated by SIGTERM")])
def test_a_signalled_serve_saves_its_metrics_and_exits_128_plus_n(name, tmp_path, sig, status, words):
    serve, driver = _serve_until(name, tmp_path, driver=True)
    serve.send_signal(sig)
    out, err = serve.communicate(timeout=60)
    assert driver is not None and driver.wait(timeout=30) == 0
    assert serve.returncode == status and len(_errors(err)) == 1 and words in _errors(err)[0], err
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["end"] == "interrupted" and metrics["simulated_time_s"] > 0.5
    assert f"metrics saved in {tmp_path}" in out


def test_serve_stopped_while_waiting_for_a_driver_still_saves_its_metrics(name, tmp_path):
    serve, _ = _serve_until(name, tmp_path, driver=False)
    serve.send_signal(signal.SIGTERM)
    _, err = serve.communicate(timeout=60)
    assert serve.returncode == 143 and len(_errors(err)) == 1, err
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["end"] == "interrupted" and metrics["simulated_time_s"] == 0.0


def test_a_signalled_in_process_drive_saves_its_metrics_too(tmp_path):
    proc = subprocess.Popen(DS + ["drive", "--world", "sidewalk", "--in-process", "--seconds", "3600", "--realtime",
                                  "--record", str(tmp_path / "run.mp4"), "--out", str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.time()
    while not list(tmp_path.glob(".run.mp4.*.tmp.mp4")):   # the video's first frames: it is driving
        assert proc.poll() is None and time.time() - t0 < 60
        time.sleep(0.1)
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143 and _errors(err) == ["drivestudio drive: terminated by SIGTERM"], err
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["end"] == "interrupted" and 0 < metrics["simulated_time_s"] < 3600
    assert (tmp_path / "run.mp4").stat().st_size > 0 and not list(tmp_path.glob(".run.mp4.*"))   # kept, whole
