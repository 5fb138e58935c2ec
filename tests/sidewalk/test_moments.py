"""Data moments through the real tooling: `drivestudio generate --world sidewalk` records the stereo pair per step
with steering, motor, behavioural and operation mode; the readers assemble MultiNet's data moment (left and right
at t - 33 ms and t, the next 10 steering and 10 motor values) without storing any image twice."""
import json

import numpy as np
import pytest

from core.worlds.sidewalk import MODES
from perception.datasets import FrameDataset
from perception.shards import Dataset, image_column
from tests.helpers import make

GENERATE = ["generate", "--world", "sidewalk", "--frames", "90",
            "--episode-frames", "30", "--set", "stereo.width=168", "--set", "stereo.height=94",
            "--paths", "park,procedural:3",
            "--workers", "2", "--seed", "5"]


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    out = tmp_path_factory.mktemp("moments") / "data"
    make(*GENERATE, "--out", out)
    return out


def test_modes_are_balanced_and_recorded(data):
    ds = Dataset(data)
    assert ds.world == "sidewalk" and len(ds.shards) == 3
    assert [s.params["mode"] for s in ds.shards] == list(MODES)
    v = ds.labels(None, ("behaviour", "operation", "correcting", "path", "steer", "motor"))
    assert np.bincount(v["behaviour"].astype(int), minlength=3).tolist() == [30, 30, 30]
    assert (v["operation"] == 0).all() and not v["correcting"].any()       # expert operation
    assert set(v["path"]) <= {"park", "procedural:3"}


def test_a_moment_is_two_stereo_pairs_and_the_next_ten_commands(data):
    ds = FrameDataset(data, None, normalised=False)
    assert ds.outputs == tuple(f"steer+{k}" for k in range(1, 11)) + tuple(f"motor+{k}" for k in range(1, 11))
    assert len(ds) == 3 * (30 - 1 - 10)                       # every step with one before it and ten after it
    reader = ds.data.reader(ds.shards[1])
    table = reader.labels(("steer", "motor", "t", "step", "behaviour"))
    steer, motor, t = (table.column(c).to_numpy() for c in ("steer", "motor", "t"))
    for i in (len(ds) // 3, len(ds) // 3 + 7):
        k, step = ds.locate(i)
        assert k == 1
        images, mode, target = ds[i]
        assert images.shape == (12, 94, 168) and str(images.dtype) == "torch.uint8" and int(mode) == 1
        np.testing.assert_allclose(target.numpy()[:10], steer[step + 1:step + 11], rtol=1e-6)
        np.testing.assert_allclose(target.numpy()[10:], motor[step + 1:step + 11], rtol=1e-6)
        assert t[step] - t[step - 1] == pytest.approx(1 / 30)          # the earlier pair is 33 ms older
        earlier, _ = reader.row(step - 1)
        now, _ = reader.row(step)
        stacked = images.numpy()
        for j, img in enumerate((*earlier, *now)):                       # left, right at t - 1; left, right at t
            np.testing.assert_array_equal(stacked[3 * j:3 * j + 3], img.transpose(2, 0, 1))


def test_images_are_stored_once(data):
    ds = Dataset(data)
    names = ds.reader(ds.shards[0])._file.schema_arrow.names
    assert [n for n in names if n.startswith("image_")] == [image_column("left"), image_column("right")]
    assert sum(s.frames for s in ds.shards) == 90


def test_same_seed_same_frames_and_labels(data, run_cli, tmp_path):
    again = tmp_path / "again"
    r = run_cli(*GENERATE, "--out", again)
    assert r.returncode == 0, r.stderr
    first = json.loads((data / "manifest.json").read_text())["shards"]
    second = json.loads((again / "manifest.json").read_text())["shards"]
    assert [s["sha256"] for s in first] == [s["sha256"] for s in second]


def test_stats_reports_the_balance(data, run_cli, tmp_path):
    r = run_cli("stats", data, "--out", tmp_path / "st")
    assert r.returncode == 0, r.stderr
    assert "direct 33.3%, follow 33.3%, furtive 33.3%" in r.stdout and "| correcting | 0.0% of frames" in r.stdout
    summary = json.loads((tmp_path / "st" / "stats.json").read_text())
    assert summary["modes"] == {"direct": 1 / 3, "follow": 1 / 3, "furtive": 1 / 3} or \
        summary["modes"] == pytest.approx({"direct": 0.3333, "follow": 0.3333, "furtive": 0.3333}, abs=1e-3)
    assert set(summary["flag_events"]) >= {"obstacle_near", "collision", "correcting"}
