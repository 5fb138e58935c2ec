"""The sidewalk world as a new user meets it: render both cameras, drive over the bridge with a video, the
Gymnasium environment; bad input is one line on stderr and exit status 2."""
import json
import os
import subprocess
import sys

import cv2
import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401  registers drivestudio/Sidewalk-v0

DS = [sys.executable, "-m", "drivestudio"]


def run(*argv, timeout=120):
    return subprocess.run(DS + [str(a) for a in argv], capture_output=True, text=True, timeout=timeout)


def test_render_writes_both_cameras(run_cli, tmp_path):
    r = run_cli("render", "--world", "sidewalk", "--path", "sidewalk", "--seed", "4", "-o", tmp_path / "f.png",
            "--truth", tmp_path / "f.json")
    assert r.returncode == 0, r.stderr
    left, right = (cv2.imread(str(tmp_path / f"f-{c}.png")) for c in ("left", "right"))
    assert left.shape == right.shape == (188, 336, 3) and not np.array_equal(left, right)
    truth = json.loads((tmp_path / "f.json").read_text())
    assert truth["path"] == "sidewalk" and truth["stereo"]["baseline_m"] == 0.12 and "border_left" in truth


def test_drive_over_the_bridge_with_a_video(tmp_path):
    proc = subprocess.Popen(DS + ["drive", "--world", "sidewalk", "--model", "expert", "--mode", "furtive", "--seconds",
                                  "4", "--record", str(tmp_path / "run.mp4"), "--out", str(tmp_path / "run")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    m = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert m["transport"] == "shared memory" and m["world"] == "sidewalk" and m["mode"] == "furtive"
    assert m["simulated_time_s"] == pytest.approx(4.0) and m["collisions"] == 0 and m["autonomy_percent"] == 100.0
    cap = cv2.VideoCapture(str(tmp_path / "run.mp4"))
    ok, frame = cap.read()
    assert ok and frame.shape[1] >= 2 * 336 + 188 and int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 120
    assert not os.path.exists(f"/dev/shm/drivestudio-{proc.pid}")      # the run's segment is gone


def test_the_poor_driver_is_corrected_over_the_bridge(tmp_path):
    r = run("drive", "--world", "sidewalk", "--model", "poor", "--seconds", "30", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["operation"] == "correctional" and m["corrections"] >= 1 and m["autonomy_percent"] < 100.0
    assert m["collisions"] == 0 and m["off_path_time_s"] == 0.0


def test_gymnasium():
    env = gym.make("drivestudio/Sidewalk-v0", mode="furtive", width=168, height=94)
    obs, info = env.reset(seed=0)
    assert obs.shape == (2, 94, 168, 3) and info["behaviour"] == 2 and info["record"].shape == (26,)
    total = 0.0
    for _ in range(30):
        obs, reward, terminated, truncated, info = env.step(np.array([0.5, 0.6], dtype=np.float32))
        total += reward
    assert total > 0.5 and not terminated and info["speed"] > 1.0
    env.close()


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize("argv, message", [
    (["render", "--mode", "sneaky"], "invalid choice: 'sneaky'"),
    (["render", "--set", "path_width=3.5"], "--set path_width must be a number from 1.5 to 3 m"),
    (["render", "--set", "path_width=nan"], "--set path_width must be a finite number"),
    (["render", "--path", "FILE:open.json"], "does not close"),
    (["render", "--path", "FILE:nan.json"], "NaN is not allowed"),
    (["render", "--obstacles", "FILE:bad.json"], "malformed JSON"),
    (["render", "--obstacles", "FILE:blocking.json"], "blocks the path"),
    (["render", "--obstacles", "nan"], "--obstacles must be a density"),
    (["generate", "--modes", "direct,sneaky", "--out", "OUT"], "unknown behavioural mode 'sneaky'"),
    (["generate", "--perturbed", "1.5", "--out", "OUT"], "--perturbed: must be in [0, 1], got 1.5"),
    (["generate", "--perturbed", "nan", "--out", "OUT"], "--perturbed: must be a finite number"),
    (["render", "--world", "highway", "--path", "park"], "--path belongs to the sidewalk world"),
])
def test_bad_input_is_one_line_and_status_2(run_cli, tmp_path, argv, message):
    files = {"open.json": json.dumps({"name": "open", "width": 2.0, "segments": [
                 {"type": "straight", "length": 50}, {"type": "arc", "radius": 5, "angle_deg": 90, "turn": "left"}]}),
             "nan.json": '{"name": "n", "width": NaN, "segments": []}',
             "bad.json": '{"obstacles": [{"kind": "cone", "s": 3,}]}',
             "blocking.json": json.dumps({"obstacles": [{"kind": "bench", "s": 30, "d": 0, "yaw_deg": 90}]})}
    argv = [write(tmp_path, a[5:], files[a[5:]]) if a.startswith("FILE:") else
            str(tmp_path / "out") if a == "OUT" else a for a in argv]
    if "--world" not in argv:
        argv[1:1] = ["--world", "sidewalk"]
    if argv[0] == "render":
        argv += ["-o", str(tmp_path / "x.png")]
    r = run_cli(*argv)   # in this process (tests/helpers.py)
    assert r.returncode == 2, r.stderr
    assert message in r.stderr and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
