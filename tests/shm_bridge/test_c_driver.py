"""The C driver of docs/shm-protocol.md, section 10, exactly as printed there, compiled with the header that
`python -m shm_bridge.layout` prints, against a real `drivestudio serve` in both worlds: it keeps the car on the
road, ends the run in order, refuses what the document says to refuse and leaves the way it says."""
from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from core.declaration import Camera
from core.worlds.highway import HIGHWAY
from shm_bridge.endpoints import DriverEndpoint, PeerGone, WorldEndpoint
from tests.shm_bridge.processes import REPO
from tests.shm_bridge.test_handshake import version_1_segment

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
SERVE = [sys.executable, "-m", "drivestudio", "serve"]


@pytest.fixture(scope="module")
def driver(tmp_path_factory) -> Path:
    """ds_driver built from the document's example and the generated header, with every warning an error."""
    work = tmp_path_factory.mktemp("c-driver")
    text = (REPO / "docs" / "shm-protocol.md").read_text(encoding="utf-8")
    example = re.search(r"<!-- example ds_driver.c -->\n```c\n(.*?)```", text, re.S).group(1)
    header = subprocess.run([sys.executable, "-m", "shm_bridge.layout"], cwd=REPO, capture_output=True, text=True,
                            check=True).stdout
    assert "#define DS_VERSION          2u" in header
    (work / "ds_bridge.h").write_text(header)
    (work / "ds_driver.c").write_text(example)
    subprocess.run(["cc", "-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-o", "ds_driver", "ds_driver.c", "-lm"],
                   cwd=work, check=True)
    return work / "ds_driver"


def _serve(name: str, out: Path, *args: str) -> subprocess.Popen:
    return subprocess.Popen(SERVE + ["--shm", name, "--out", str(out), "--wait", "60", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _drive(driver: Path, name: str, *args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([str(driver), name, *args], capture_output=True, text=True, timeout=timeout)


def _metrics(out: Path) -> dict:
    return json.loads((out / "metrics.json").read_text())


def test_it_keeps_the_highway_car_in_its_lane_among_traffic(driver, name, tmp_path):
    serve = _serve(name, tmp_path, "--track", "oval", "--lanes", "3", "--cars", "6", "--seconds", "20")
    r = _drive(driver, name)
    _, err = serve.communicate(timeout=120)
    assert serve.returncode == 0, err
    assert r.returncode == 0, r.stderr
    assert r.stderr == "drove 200 frames up to t = 19.90 s; the world ended the run (end_reason 1)\n"
    m = _metrics(tmp_path)
    assert m["end"] == "finished" and m["simulated_time_s"] == 20.0
    assert m["off_road_events"] == 0 and m["collisions"] == 0 and m["in_lane_share"] == 1.0
    assert m["mean_speed_mps"] > 12.0


def test_it_follows_the_sidewalk_path_alone(driver, name, tmp_path):
    serve = _serve(name, tmp_path, "--world", "sidewalk", "--operation", "autonomous", "--obstacles", "none",
                   "--seconds", "10")
    r = _drive(driver, name)
    _, err = serve.communicate(timeout=120)
    assert serve.returncode == 0, err
    assert r.returncode == 0, r.stderr
    assert r.stderr == "drove 300 frames up to t = 9.97 s; the world ended the run (end_reason 1)\n"
    m = _metrics(tmp_path)
    assert m["end"] == "finished" and m["autonomy_percent"] == 100.0
    assert m["off_path_events"] == 0 and m["collisions"] == 0 and m["distance_m"] > 10.0


def _dead_world_leftover(name: str) -> int:
    """/dev/shm/NAME left by a world process killed with SIGKILL; returns its inode."""
    code = (f"import os, time; from core.worlds.highway import HIGHWAY; from shm_bridge.endpoints import "
            f"WorldEndpoint; w = WorldEndpoint({name!r}, HIGHWAY); print('ready', flush=True); time.sleep(60)")
    proc = subprocess.Popen([sys.executable, "-c", code], cwd=REPO, stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None and proc.stdout.readline() == "ready\n"
    proc.kill()
    proc.wait()
    return os.stat(f"/dev/shm/{name}").st_ino


def test_it_removes_a_leftover_waits_for_the_world_and_finishes_the_run(driver, name, tmp_path):
    leftover = _dead_world_leftover(name)
    proc = subprocess.Popen([str(driver), name, "50"], stderr=subprocess.PIPE, text=True)
    t0 = time.time()
    while os.path.exists(f"/dev/shm/{name}") and time.time() - t0 < 10:
        time.sleep(0.02)
    assert not os.path.exists(f"/dev/shm/{name}") and proc.poll() is None   # removed; still waiting
    serve = _serve(name, tmp_path, "--track", "oval", "--cars", "0", "--seconds", "60")
    _, derr = proc.communicate(timeout=120)
    _, err = serve.communicate(timeout=120)
    assert proc.returncode == 0 and derr == "drove 50 frames; ending the run\n", derr
    assert serve.returncode == 0, err
    m = _metrics(tmp_path)
    assert m["end"] == "driver finished" and m["simulated_time_s"] == 5.0
    assert leftover and not os.path.exists(f"/dev/shm/{name}")


def test_it_refuses_a_version_1_segment_naming_both_versions(driver, name):
    version_1_segment(name, os.getpid())
    try:
        r = _drive(driver, name)
    finally:
        os.unlink(f"/dev/shm/{name}")
    assert r.returncode == 2 and r.stderr == f"shared memory '{name}' has protocol version 1, this driver speaks 2\n"


def test_it_refuses_a_second_driver_and_a_symbolic_link(driver, name, tmp_path):
    with WorldEndpoint(name, HIGHWAY), DriverEndpoint(name, attach_timeout=1):
        r = _drive(driver, name)
    assert r.returncode == 2 and "already has a driver" in r.stderr and r.stderr.count("\n") == 1
    os.symlink(tmp_path / "elsewhere", f"/dev/shm/{name}")
    try:
        r = _drive(driver, name)
    finally:
        os.unlink(f"/dev/shm/{name}")
    assert r.returncode == 2 and "is a symbolic link" in r.stderr


def test_it_refuses_a_world_it_cannot_drive(driver, name):
    rear_only = replace(HIGHWAY, cameras=(Camera("rear", 4, 4),))
    with WorldEndpoint(name, rear_only):
        r = _drive(driver, name, timeout=20)
    assert r.returncode == 2 and "lacks a highway value this driver needs (front," in r.stderr


def test_a_dead_world_is_noticed_and_its_segment_removed(driver, name):
    code = (f"import sys, time, numpy as np; from core.worlds.highway import HIGHWAY; from shm_bridge.endpoints "
            f"import WorldEndpoint; w = WorldEndpoint({name!r}, HIGHWAY); w.wait_for_driver(30); "
            "w.publish([np.zeros((210, 280, 3), np.uint8)], np.zeros(len(HIGHWAY.truth))); "
            "w.wait_action(1); print('answered', flush=True); time.sleep(60)")
    world = subprocess.Popen([sys.executable, "-c", code], cwd=REPO, stdout=subprocess.PIPE, text=True)
    proc = subprocess.Popen([str(driver), name], stderr=subprocess.PIPE, text=True)
    assert world.stdout is not None and world.stdout.readline() == "answered\n"
    world.kill()
    world.wait()
    _, err = proc.communicate(timeout=10)
    assert proc.returncode == 1 and err == f"the world process (pid {world.pid}) died\n"
    assert not os.path.exists(f"/dev/shm/{name}")


def test_an_interrupted_driver_leaves_with_status_driving(driver, name):
    """SIGTERM: the driver detaches without a status (section 8), the world takes it as a run gone wrong."""
    with WorldEndpoint(name, HIGHWAY) as world:
        proc = subprocess.Popen([str(driver), name], stderr=subprocess.PIPE, text=True)
        world.wait_for_driver(timeout=30)
        world.publish([np.zeros((210, 280, 3), np.uint8)], np.zeros(len(HIGHWAY.truth)))
        assert world.wait_action(1, timeout=10).seq == 1
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 128 + signal.SIGTERM
        with pytest.raises(PeerGone, match="closed the connection") as gone:
            world.wait_action(2, timeout=10)
        assert gone.value.orderly and not gone.value.finished and world.driver_status == "driving"
