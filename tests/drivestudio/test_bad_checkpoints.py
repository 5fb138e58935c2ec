"""A checkpoint that cannot be used is refused by every verb that reads one, in one line with exit status 2, before
any work (no world started, no output written): random bytes, a truncated file, a model of another world, weights
that are not finite, a byte flipped inside a tensor (docs/errors.md, Checkpoints)."""
from __future__ import annotations

import os
import random
import shutil
import time
from pathlib import Path

import pytest
import torch

from core.worlds.highway import HIGHWAY
from core.worlds.sidewalk import SIDEWALK
from perception.checkpoint import save_checkpoint
from perception.models import Regressor, make_spec

REPO = Path(__file__).resolve().parents[2]
SMALL = REPO / "tests" / "dataset" / "fixtures" / "highway-10"


def _save(path: Path, model: Regressor) -> None:
    save_checkpoint(path, {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})


@pytest.fixture(scope="module")
def bad(tmp_path_factory) -> dict[str, Path]:
    """One file per kind of bad checkpoint, all claiming to be highway models (but the foreign one)."""
    root = tmp_path_factory.mktemp("bad-checkpoints")
    torch.manual_seed(0)
    gist = Regressor(make_spec("gist", HIGHWAY))
    _save(root / "good.pt", gist)
    with torch.no_grad():
        gist.net.bias[0] = float("nan")
    _save(root / "nan.pt", gist)
    # random bytes that begin as a pickle of an unknown protocol would (torch warns of it: one line is still ours)
    (root / "random.pt").write_bytes(b"\x80\xaa" + random.Random(0).randbytes(4094))
    data = (root / "good.pt").read_bytes()
    (root / "truncated.pt").write_bytes(data[: len(data) // 2])
    flipped = bytearray(data)
    raw = gist.state_dict()["net.weight"].contiguous().view(torch.uint8).numpy().tobytes()
    flipped[flipped.find(raw) + 100] ^= 0x01
    (root / "flipped.pt").write_bytes(bytes(flipped))
    _save(root / "foreign.pt", Regressor(make_spec("z2color", SIDEWALK)))
    return {p.stem: p for p in root.iterdir()}


def _refused(r, *words: str) -> None:
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    assert all(w in r.stderr for w in words), r.stderr


WHY = {"random": "not a drivestudio checkpoint", "truncated": "truncated or corrupt",
       "foreign": "sidewalk world, not of the highway world", "nan": "not finite",
       "flipped": "is damaged"}


@pytest.mark.parametrize("kind", ["random", "truncated", "foreign"])
def test_drive_refuses_a_bad_checkpoint_before_the_world_starts(bad, run_cli, tmp_path, kind):
    t0 = time.monotonic()
    r = run_cli("drive", "--model", bad[kind], "--seconds", "1", "--out", tmp_path / "run")
    _refused(r, WHY[kind])
    assert "waiting for a driver" not in r.stderr and not (tmp_path / "run").exists()
    assert time.monotonic() - t0 < 60


@pytest.mark.parametrize("kind", ["nan"])
def test_drive_shm_refuses_a_bad_checkpoint_before_attaching(bad, run_cli, kind):
    t0 = time.monotonic()   # no world serves this name: attaching would wait 30 s before failing
    r = run_cli("drive", "--shm", f"no-world-{os.getpid()}", "--model", bad[kind])
    _refused(r, WHY[kind])
    assert time.monotonic() - t0 < 25


def _verbs(ckpt: str, out: Path) -> dict[str, list[str]]:
    return {
        "evaluate": ["evaluate", "--data", str(SMALL), "--model", ckpt, "--out", str(out / "eval")],
        "overlay": ["overlay", "--data", str(SMALL), "--model", ckpt, "--out", str(out / "overlays")],
        "export": ["export", "--model", ckpt, "--onnx", str(out / "m.onnx")],
        "benchmark": ["benchmark", "--model", ckpt, "--out", str(out / "bench")],
        "aggregate": ["aggregate", "--data", str(SMALL), "--model", ckpt, "--out", str(out / "agg"), "--rounds", "1"],
        "train --init": ["train", "--data", str(SMALL), "--model", "alexnet", "--init", ckpt, "--out",
                         str(out / "t.pt")],
    }


# each verb with one of the two kinds of damaged weights (both kinds, verb by verb, would double a slow test)
@pytest.mark.parametrize("verb, kind", [(verb, ("nan", "flipped")[i % 2])
                                        for i, verb in enumerate(_verbs("x", Path()))])
def test_every_verb_refuses_damaged_weights(bad, run_cli, tmp_path, verb, kind):
    work = tmp_path / "work"
    work.mkdir()
    shutil.copy(bad[kind], work / "model.pt")
    before = sorted(p.name for p in work.iterdir())
    r = run_cli(*_verbs(str(work / "model.pt"), work)[verb])
    _refused(r, WHY[kind])
    assert sorted(p.name for p in work.iterdir()) == before   # nothing written beside it
