"""The closed loop as users run it: real processes, real shared memory, real SUMO."""
import json
import os
import signal
import subprocess
import sys
import time

import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401  registers drivestudio/Highway-v0
from controller.highway import ChenController
from tests.helpers import driven_frames

DRIVE = [sys.executable, "-m", "drivestudio", "drive"]
WORLD = ["--track", "oval", "--lanes", "3", "--cars", "6"]


def shm_entries(*pids):
    """The segments of the runs of these processes (drivestudio-PID, and their names with suffixes) still in /dev/shm:
    other runs on the machine (another test, a user's) are not this test's."""
    return [n for n in os.listdir("/dev/shm") for pid in pids
            if n == f"drivestudio-{pid}" or n.startswith(f"drivestudio-{pid}-")]


def run(argv):
    """subprocess.run with the process id kept (the name of its segment)."""
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = proc.communicate(timeout=120)
    return subprocess.CompletedProcess(argv, proc.returncode, out, err), proc.pid


def metrics_of(out):
    return json.loads((out / "metrics.json").read_text())


def test_oracle_over_shared_memory_and_in_process_drive_the_same(tmp_path):
    shm, shm_pid = run(DRIVE + WORLD + ["--seconds", "20", "--out", str(tmp_path / "shm")])
    assert shm.returncode == 0, shm.stderr
    one, one_pid = run(DRIVE + WORLD + ["--seconds", "20", "--in-process", "--out", str(tmp_path / "one")])
    assert one.returncode == 0, one.stderr
    a, b = metrics_of(tmp_path / "shm"), metrics_of(tmp_path / "one")
    assert a["transport"] == "shared memory" and b["transport"] == "in process"
    for key in ("distance_m", "lane_changes", "overtakes", "overtaken", "collisions", "in_lane_share"):
        assert a[key] == b[key], key  # one loop, two transports
    assert a["simulated_time_s"] == 20.0 and a["collisions"] == 0 and a["off_road_events"] == 0
    assert a["stage_ms_per_step"]["render"] > 0 and a["stage_ms_per_step"]["transfer"] > 0
    assert "| mean_speed_mps |" in shm.stdout and (tmp_path / "shm" / "metrics.md").exists()
    assert shm_entries(shm_pid, one_pid) == []


def test_serve_and_drive_as_two_commands(tmp_path):
    name = f"ds-test-{os.getpid()}"
    serve = subprocess.Popen([sys.executable, "-m", "drivestudio", "serve", "--shm", name, *WORLD, "--seconds", "10",
                              "--free-running", "--out", str(tmp_path)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    drive = subprocess.run(DRIVE + ["--shm", name, "--model", "oracle"], capture_output=True, text=True, timeout=120)
    out, err = serve.communicate(timeout=120)
    assert serve.returncode == 0, err
    assert drive.returncode == 0, drive.stderr
    m = metrics_of(tmp_path)
    assert m["simulated_time_s"] == 10.0 and m["lockstep"] is False
    assert not os.path.exists(f"/dev/shm/{name}")


def _start_both(tmp_path):
    proc = subprocess.Popen(DRIVE + WORLD + ["--seconds", "600", "--out", str(tmp_path)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    # running once the driver child exists and has taken 20 frames of the world's (its segment says so)
    t0 = time.time()
    while time.time() - t0 < 60:
        kids = subprocess.run(["ps", "-o", "pid=", "--ppid", str(proc.pid)], capture_output=True, text=True)
        if kids.stdout.split() and driven_frames(f"drivestudio-{proc.pid}") >= 20:
            return proc, int(kids.stdout.split()[0])
        time.sleep(0.05)
    proc.kill()
    raise AssertionError("the run did not start")


def _time_to_exit(pid, popen=None, limit=10.0):
    t0 = time.time()
    while time.time() - t0 < limit:
        if popen is not None and popen.poll() is not None:
            return time.time() - t0
        if popen is None:
            try:
                state = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0]
            except FileNotFoundError:
                return time.time() - t0
            if state == "Z":
                return time.time() - t0
        time.sleep(0.02)
    return float("inf")


def test_killing_the_driver_ends_the_world_within_two_seconds(tmp_path):
    proc, child = _start_both(tmp_path)
    os.kill(child, signal.SIGKILL)
    assert _time_to_exit(proc.pid, proc) < 2.0
    err = proc.stderr.read()
    assert proc.returncode == 1
    assert f"the driver process (pid {child}) died" in err and "Traceback" not in err
    assert shm_entries(proc.pid) == []


def test_killing_the_world_ends_the_driver_within_two_seconds(tmp_path):
    proc, child = _start_both(tmp_path)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert _time_to_exit(child) < 2.0
    assert shm_entries(proc.pid) == []


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_stopping_the_run_cleans_up(tmp_path, sig):
    proc, child = _start_both(tmp_path)
    proc.send_signal(sig)
    assert _time_to_exit(proc.pid, proc) < 5.0
    assert _time_to_exit(child) < 5.0
    assert shm_entries(proc.pid) == []


def test_bad_model_is_one_line(tmp_path):
    r = subprocess.run(DRIVE + ["--model", str(tmp_path / "nope.ckpt"), "--seconds", "1"], capture_output=True,
                       text=True)
    assert r.returncode == 2 and "no such file" in r.stderr and r.stderr.count("\n") == 1


def test_attaching_to_a_missing_world_fails_clearly():
    t0 = time.monotonic()
    r = subprocess.run(DRIVE + ["--shm", "no-such-world-here", "--attach-wait", "2"], capture_output=True, text=True,
                       timeout=60, env={**os.environ})
    assert r.returncode != 0 and "no-such-world-here" in r.stderr and "Traceback" not in r.stderr
    assert time.monotonic() - t0 < 20    # it waited the 2 s asked for, not the default 30


def test_a_controller_drives_the_gymnasium_environment():
    env = gym.make("drivestudio/Highway-v0", track="oval", lanes=3, cars=6)
    frame, info = env.reset(seed=3)
    assert frame.shape == (210, 280, 3) and info["indicators"].shape == (14,)
    ctrl = ChenController(info["lanes"])
    total = 0.0
    for _ in range(150):
        a = ctrl.act(info["indicators"], info["speed"])
        frame, reward, terminated, truncated, info = env.step(np.array([a.steer, a.accel, a.brake]))
        total += reward
        assert not terminated and not info["collision"]
    assert total > 150 * 0.1 * 10  # faster than 10 m/s on average
    env.close()


DRIVER_SCRIPT = r'''
import sys, time
from shm_bridge.endpoints import DriverEndpoint
from core.worlds.highway import Action
name = sys.argv[1]
with DriverEndpoint(name, attach_timeout=60) as ep:
    ep.driver_mode = "manual"          # an expert takes over: our (absurd) commands must not steer the car
    n = 0
    while (msg := ep.wait_frame()) is not None:
        n += 1
        if n == 20:
            ep.paused = True           # the world must hold still while paused
            time.sleep(1.0)
            print("t at pause", msg.t, flush=True)
            ep.paused = False
        ep.send_action(msg.seq, Action(steer=1.0, accel=1.0, brake=0.0))
    print("frames", n, flush=True)
'''


def test_manual_mode_and_pause_flags_are_honoured(tmp_path):
    name = f"ds-flags-{os.getpid()}"
    serve = subprocess.Popen([sys.executable, "-m", "drivestudio", "serve", "--shm", name, *WORLD, "--seconds", "8",
                              "--out", str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.time()
    driver = subprocess.run([sys.executable, "-c", DRIVER_SCRIPT, name], capture_output=True, text=True, timeout=120)
    serve.communicate(timeout=120)
    assert driver.returncode == 0, driver.stderr
    assert "frames 80" in driver.stdout
    m = metrics_of(tmp_path)
    assert m["off_road_events"] == 0 and m["collisions"] == 0  # full left lock would have left the road
    assert time.time() - t0 > 1.0
