"""Every bad input gets one line on stderr and exit status 2, before any work, and damages nothing (docs/errors.md).

Each case runs the real command in a folder holding a small dataset, a checkpoint, a track and a scenario; after it
the folder's files are byte for byte what they were, and nothing the command should not have written exists.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SMALL = REPO / "tests" / "dataset" / "fixtures" / "highway-10"


@pytest.fixture(scope="module")
def fixture(tmp_path_factory) -> Path:
    """data/ (a small highway dataset), model.pt (a GIST checkpoint), track.json, scenario.json, a FIFO, a socket,
    a symbolic link to /dev/null, a regular file called file.txt."""
    root = tmp_path_factory.mktemp("bad-input")
    shutil.copytree(SMALL, root / "data")
    from drivestudio.cli import main
    assert main(["train", "--data", str(root / "data"), "--model", "gist", "--out", str(root / "model.pt")]) == 0
    shutil.copy(REPO / "docs" / "examples" / "three-lane.json", root / "scenario.json")
    shutil.copy(REPO / "assets" / "tracks" / "oval.json", root / "track.json")
    (root / "file.txt").write_text("keep me\n")
    os.mkfifo(root / "fifo.png")
    s = socket.socket(socket.AF_UNIX)
    s.bind(str(root / "sock.png"))
    s.close()
    os.symlink("/dev/null", root / "null.png")
    (root / "deep.json").write_text("[" * 200_000 + "]" * 200_000)
    (root / "latin1.json").write_bytes('{"name": "caf\xe9"}'.encode("latin-1"))
    return root


def snapshot(root: Path) -> dict:
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in filenames + dirnames:
            p = Path(dirpath) / name
            rel = str(p.relative_to(root))
            if p.is_symlink():
                out[rel] = "-> " + os.readlink(p)
            elif p.is_file() and not p.is_fifo():
                out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
            else:
                out[rel] = "special" if not p.is_dir() else "dir"
    return out


D = "{root}/data"
M = "{root}/model.pt"
CASES = [
    # output paths: refused before any work
    ("render", "-o", "/proc/x.png"),
    ("render", "-o", "{root}"),
    ("render", "-o", "{root}/x.jpg"),
    ("render", "-o", "{root}/fifo.png"),
    ("render", "-o", "{root}/sock.png"),
    ("render", "-o", "{root}/null.png"),
    ("render", "-o", "/dev/full"),
    ("render", "-o", ""),
    ("render", "-o", "{root}/file.txt/x.png"),
    ("render", "-o", "{root}/f.png", "--truth", "{root}/t.txt"),
    ("generate", "--out", "{root}/file.txt", "--frames", "10"),
    ("generate", "--out", "/proc/nope/ds", "--frames", "10"),
    ("generate", "--out", "", "--frames", "10"),
    ("train", "--data", D, "--model", "gist", "--out", "/proc/x.pt"),
    ("train", "--data", D, "--model", "gist", "--out", "{root}"),
    ("train", "--data", D, "--model", "gist", "--out", "{root}/null.png"),
    ("evaluate", "--data", D, "--model", M, "--out", "{root}/file.txt"),
    ("overlay", "--data", D, "--out", "{root}/file.txt"),
    ("overlay", "--data", D, "--video", "{root}/x.avi"),
    ("stats", D, "--out", "{root}/file.txt"),
    ("drive", "--seconds", "1", "--record", "{root}/x.avi"),
    ("drive", "--seconds", "1", "--out", "{root}/file.txt"),
    ("serve", "--shm", "ok", "--seconds", "1", "--out", "/proc/x"),
    # numbers
    ("render", "--set", "camera.fov_deg=nan", "-o", "{root}/f.png"),
    ("render", "--set", "camera.fov_deg=0", "-o", "{root}/f.png"),
    ("render", "--warmup", "nan", "-o", "{root}/f.png"),
    ("render", "--seed", "-1", "-o", "{root}/f.png"),
    ("render", "--set", "camera.width=100000", "-o", "{root}/f.png"),
    ("drive", "--seconds", "nan"),
    ("drive", "--seconds", "-5"),
    ("drive", "--seconds", "0"),
    ("drive", "--seconds", "inf"),
    ("drive", "--set", "start_speed=-10"),
    ("drive", "--set", "start_speed"),
    ("drive", "--set", "no_such=1"),
    ("drive", "--set", "mirror=perhaps"),
    ("drive", "--cars", "-1"),
    ("drive", "--device", "banana"),
    ("serve", "--shm", "ok", "--wait", "-1"),
    ("generate", "--out", "{root}/g", "--procedural", "-1"),
    ("generate", "--out", "{root}/g", "--tracks", ","),
    ("generate", "--out", "{root}/g", "--frames", "-5"),
    ("generate", "--out", "{root}/g", "--workers", "0"),
    ("generate", "--out", "{root}/g", "--cars", "30-12"),
    ("generate", "--out", "{root}/g", "--cars", "many"),
    ("train", "--data", D, "--model", "alexnet", "--out", "{root}/a.pt", "--lr", "nan"),
    ("train", "--data", D, "--model", "alexnet", "--out", "{root}/a.pt", "--batch-size", "0"),
    ("train", "--data", D, "--model", "alexnet", "--out", "{root}/a.pt", "--device", "banana"),
    ("train", "--data", D, "--model", "resnet", "--out", "{root}/a.pt"),
    ("train", "--data", D, "--model", "mobilenet", "--out", "{root}/a.pt", "--set", "loss=l3"),
    ("train", "--data", D, "--model", "mobilenet", "--out", "{root}/a.pt", "--set", "ema=1.5"),
    ("train", "--data", D, "--model", "gist", "--out", "{root}/g.pt", "--set", "loss=l1"),
    ("train", "--data", D, "--model", "mobilenet", "--out", "{root}/a.pt", "--set", "emphasis=0"),
    ("train", "--data", D, "--model", "gist", "--out", "{root}/g.pt", "--set", "emphasis=3"),
    ("train", "--data", D, "--model", "alexnet", "--out", "{root}/a.pt", "--set", "steer_share=0.5"),
    ("train", "--data", D, "--model", "z2color", "--out", "{root}/z.pt", "--set", "steer_share=1.5"),
    ("train", "--data", D, "--model", "alexnet", "--out", "{root}/a.pt", "--set", "lr_step=0"),
    ("train", "--data", D, "--model", "alexnet", "--out", "{root}/a.pt", "--set", "nope=1"),
    ("study", "--set", "steer_share=-0.1", "--out", "{root}/study"),
    ("demo", "--frames", "-5", "--out", "{root}/demo"),
    ("recipe", "--set", "emphasis=0", "--out", "{root}/recipe"),
    ("recipe", "--set", "rounds=2", "--out", "{root}/recipe"),         # rounds fine-tune one network, not three
    ("recipe", "--set", "members=0", "--out", "{root}/recipe"),
    ("recipe", "--set", "members=9", "--out", "{root}/recipe"),
    ("recipe", "--extended", "--set", "cars=12-400", "--out", "{root}/recipe"),
    ("recipe", "--suite", "{root}/deep.json", "--out", "{root}/recipe"),  # a bad suite: refused before training
    # files and their content
    ("probe", "/dev/zero"),
    ("probe", "{root}/deep.json"),
    ("probe", "{root}/latin1.json"),
    ("probe", "{root}/fifo.png"),
    ("probe", "{root}"),
    ("probe", "{root}/missing.json"),
    ("render", "--track", "{root}/deep.json", "-o", "{root}/f.png"),
    ("stats", "{root}/file.txt"),
    ("stats", "{root}/missing"),
    ("evaluate", "--data", D, "--model", "{root}/file.txt", "--out", "{root}/ev"),
    ("evaluate", "--data", D, "--model", "{root}/missing.pt", "--out", "{root}/ev"),
    ("train", "--data", "{root}/missing", "--model", "gist", "--out", "{root}/g.pt"),
    # shared-memory names: usage errors
    ("drive", "--shm", "../x"),
    ("drive", "--shm", "a/b"),
    ("drive", "--shm", ""),
    ("drive", "--shm", ".x"),
    ("drive", "--shm", "x" * 300),
    ("serve", "--shm", "-x", "--seconds", "1"),
    # options of another world, and worlds that do not exist
    ("drive", "--world", "atlantis"),
    ("render", "--world", "highway", "--path", "park", "-o", "{root}/f.png"),
]


def _ids(case):
    return " ".join(case)[:60]


def _refused_with_one_line(fixture, before, r):
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("drivestudio"), r.stderr
    assert "Traceback" not in r.stderr
    assert snapshot(fixture) == before, "the command changed the fixture"
    assert os.path.exists("/dev/full") and not os.path.isfile("/dev/full")
    assert not (fixture / "runs").exists(), "a refused command made its output folder"


# in this process, through the command line's entry point (tests/helpers.py): the same exit status and streams
@pytest.mark.parametrize("case", CASES, ids=[_ids(c) for c in CASES])
def test_bad_input_gets_one_line_and_status_2(fixture, run_cli, case):
    before = snapshot(fixture)
    r = run_cli(*[a.format(root=fixture) for a in case], cwd=fixture)
    _refused_with_one_line(fixture, before, r)


# the line names what the option takes there, and the verb that refused it
MESSAGES = [
    (("aggregate", "--data", D, "--model", "oracle", "--out", "{root}/agg"),
     "drivestudio aggregate: error: --model must be a checkpoint file; no such file: oracle"),
    (("drive", "--model", "{root}/missing.pt"), "a world's driver (oracle, oracle-extended, expert) or a checkpoint"),
    (("drive", "--world", "sidewalk", "--model", "{root}/missing.pt"), "a world's driver (expert, poor, oracle) or"),
    (("ppo", "--timesteps", "0"), "drivestudio ppo: error: unrecognized arguments: --timesteps 0"),
    (("render", "-o", "{root}/f.png", "--frobnicate"), "drivestudio render: error: unrecognized arguments: --frob"),
]


@pytest.mark.parametrize("case,says", MESSAGES, ids=[_ids(c) for c, _ in MESSAGES])
def test_the_line_names_what_the_option_takes(fixture, run_cli, case, says):
    before = snapshot(fixture)
    r = run_cli(*[a.format(root=fixture) for a in case], cwd=fixture)
    _refused_with_one_line(fixture, before, r)
    assert says in r.stderr, r.stderr

# and from a real interpreter, as a shell sees it: an option's number (argparse) and a file's content (the verb)
@pytest.mark.parametrize("case", [("drive", "--seconds", "nan"), ("probe", "{root}/deep.json")], ids=_ids)
def test_bad_input_from_a_real_process_gets_one_line_and_status_2(fixture, case):
    before = snapshot(fixture)
    argv = [a.format(root=fixture) for a in case]
    r = subprocess.run([sys.executable, "-m", "drivestudio", *argv], cwd=fixture, capture_output=True, text=True,
                       timeout=120)
    _refused_with_one_line(fixture, before, r)


def test_a_kill_during_a_save_leaves_nothing_behind_for_long(tmp_path):
    """A temporary of a writer that died (kill -9 during a checkpoint save) is removed by the next write there."""
    from core.files import atomic_write, temporary_for
    target = tmp_path / "model.pt"
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    orphan = tmp_path / f".model.pt.{dead.pid}.0.tmp"
    orphan.write_bytes(b"x" * 1000)
    live = temporary_for(target)   # this process's own: kept
    live.write_bytes(b"y")
    atomic_write(target, b"checkpoint")
    assert target.read_bytes() == b"checkpoint" and not orphan.exists() and live.exists()


def test_write_never_replaces_a_special_file(tmp_path):
    from core.files import OutputError, atomic_write
    os.mkfifo(tmp_path / "pipe")
    with pytest.raises(OutputError, match="FIFO"):
        atomic_write(tmp_path / "pipe", b"data")
    os.symlink("/dev/null", tmp_path / "link")
    with pytest.raises(OutputError, match="device"):
        atomic_write(tmp_path / "link", b"data")
    assert (tmp_path / "pipe").is_fifo() and os.readlink(tmp_path / "link") == "/dev/null"
    (tmp_path / "real").write_bytes(b"old")
    os.symlink(tmp_path / "real", tmp_path / "to-real")
    atomic_write(tmp_path / "to-real", b"new")          # a link to a regular file: the file is replaced
    assert (tmp_path / "real").read_bytes() == b"new" and (tmp_path / "to-real").is_symlink()


@pytest.mark.long
def test_training_saves_on_sigterm_and_by_the_clock(tmp_path):
    """Checkpoints are written at validations, every checkpoint_every seconds and on SIGTERM: a kill between
    validations loses little, and the same command continues."""
    import signal
    import time

    import torch

    from tests.helpers import make
    worlds = {"DRIVESTUDIO_WORLDS": "tests.drivestudio.tiny_world:Plugin", "PYTHONPATH": str(REPO)}
    env = {**os.environ, **worlds}
    data = tmp_path / "data"
    make("generate", "--world", "corridor", "--out", data, "--frames", "200", "--episode-frames", "20", "--workers",
         "1", env=worlds)
    out = tmp_path / "tiny.pt"
    cmd = [sys.executable, "-m", "drivestudio", "train", "--data", str(data), "--model", "tinyconv", "--out", str(out),
           "--iterations", "10000000", "--batch-size", "4", "--set", "val_every=10000000", "--set",
           "checkpoint_every=0.5", "--device", "cpu", "--workers", "0", "--set", "optimizer=adam", "--lr", "1e-3"]
    proc = subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.time()
    while not out.exists() and time.time() - t0 < 120:   # a save by the clock, long before any validation
        time.sleep(0.2)
    assert out.exists(), "no checkpoint by the clock"
    first = torch.load(out, weights_only=True)["train"]["iteration"]
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    out_text, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM and "interrupted: saved" in out_text + err
    assert "Traceback" not in err
    last = torch.load(out, weights_only=True)["train"]["iteration"]
    assert 0 < first <= last < 10000000
    assert not list(tmp_path.glob(".tiny.pt.*.tmp"))
    r = subprocess.run(cmd[:cmd.index("--iterations") + 1] + [str(last + 5)] + cmd[cmd.index("--iterations") + 2:],
                       cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and f"continuing {out} from iteration {last}" in r.stdout + r.stderr
