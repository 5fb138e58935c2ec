"""Dataset generation with real workers, real SUMO and real rendering; kill and resume with real processes."""
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from drivestudio import worlds
from perception.shards import Dataset, DatasetError, ShardReader, read_manifest, split_of

SMALL = ["--frames", "60", "--episode-frames", "20", "--tracks", "oval,hairpins", "--lanes", "2,3",
         "--cars", "6", "--set", "camera.width=140", "--set", "camera.height=105"]


def generate(run_cli, out, *extra, workers=1, check=True, env=None):
    """`drivestudio generate` in this process (its workers are processes of their own all the same), `env` added to
    its environment."""
    r = run_cli("generate", "--out", out, *SMALL, "--workers", workers, *extra, env=env)
    if check:
        assert r.returncode == 0, r.stderr[-3000:]
    return r


def content(root: Path) -> dict:
    """episode -> (labels table as python, image bytes) for comparing datasets."""
    out = {}
    for s in Dataset(root).shards:
        table = pq.read_table(root / s.file)
        out[s.episode] = table.to_pylist()
    return out


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    from drivestudio.cli import main
    root = tmp_path_factory.mktemp("ref") / "ds"
    assert main(["generate", "--out", str(root), *SMALL, "--workers", "2"]) == 0
    return root


def test_generate_writes_the_frames_and_a_manifest(reference):
    m = read_manifest(reference)
    assert m["version"] == 2 and m["complete"] and m["frames"] == 60 and len(m["shards"]) == 3
    assert m["renderer"] == "numba" and m["software"]["pybullet"] and m["config"]["seed"] == 0
    assert m["world"]["name"] == "highway" and m["world"]["cameras"][0] == {"name": "front", "height": 105,
                                                                            "width": 140, "channels": 3}
    ds = Dataset(reference)
    assert ds.world == "highway" and ds.declaration.cameras[0].shape == (105, 140, 3)
    assert [s.episode for s in ds.shards] == [0, 1, 2]
    assert [s.params["lanes"] for s in ds.shards] == [2, 3, 2]
    assert [s.params["track"] for s in ds.shards] == ["oval", "oval", "hairpins"]
    for s in ds.shards:   # each shard's size and checksum are in the manifest
        assert s.size == (reference / s.file).stat().st_size and len(s.sha256) == 64 and ds.verify(s) is None
    images, rec = ds.reader(ds.shards[1]).row(7)
    assert len(images) == 1 and images[0].shape == (105, 140, 3) and images[0].dtype == np.uint8
    assert rec["episode"] == 1 and rec["step"] == 7 and rec["lanes"] == 3
    assert {"x", "y", "yaw", "s", "d", "collision", "off_road"} <= set(rec)
    assert len(rec["action"]) == 3 and rec["track"] == "oval"
    assert rec["t"] == pytest.approx(5.0 + 0.7)   # after 5 s of unrecorded warm-up
    assert not list(reference.glob(".*.tmp"))
    assert pq.read_schema(reference / ds.shards[0].file).names[0] == "image_front"


def test_split_is_by_whole_episode():
    assert [split_of(k) for k in range(12)] == ["train"] * 8 + ["val", "test", "train", "train"]


@pytest.mark.parametrize("lanes", [(1, 2, 3), (1, 2, 3, 4), (2, 4), (1, 2, 3, 4, 5)])
def test_every_split_meets_every_lane_count(lanes):
    highway = worlds.get("highway")
    options = {"tracks": ("oval", "s-curve"), "procedural": 0, "lanes": lanes, "cars": (12, 12)}
    episodes = highway.plan(options, 100 * 500, 500, 0)
    for split in ("train", "val", "test"):
        met = {ep.params["lanes"] for ep in episodes if split_of(ep.index) == split}
        assert met == set(lanes), (split, met)
    for n in lanes:   # and the tracks still meet every lane count
        assert {ep.params["track"] for ep in episodes if ep.params["lanes"] == n} == {"oval", "s-curve"}


def test_three_lane_counts_keep_the_plain_cycle():
    """Datasets made with the default 1-3 lanes continue on the plan that made them."""
    options = {"tracks": ("oval",), "procedural": 0, "lanes": (1, 2, 3), "cars": (12, 12)}
    episodes = worlds.get("highway").plan(options, 30 * 500, 500, 0)
    assert [ep.params["lanes"] for ep in episodes] == [1, 2, 3] * 10


def test_same_options_same_dataset(reference, run_cli, tmp_path):
    again = tmp_path / "again"
    generate(run_cli, again, workers=1)
    assert content(again) == content(reference)


def _wait_for(predicate, timeout):
    t0 = time.time()
    while time.time() - t0 < timeout:
        if predicate():
            return True
        time.sleep(0.05)
    return False


def _children_of(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True).stdout
    return [int(x) for x in out.split()]


@pytest.mark.parametrize("sig", [signal.SIGKILL, pytest.param(signal.SIGINT, marks=pytest.mark.long)])
def test_killed_run_resumes_without_loss_or_duplicates(reference, run_cli, tmp_path, sig):
    out = tmp_path / "ds"
    cmd = [sys.executable, "-m", "drivestudio", "generate", "--out", str(out), *SMALL, "--workers", "2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert _wait_for(lambda: any(out.glob("shard-*.parquet")) or any(out.glob(".shard-*.tmp")), 120)
    workers = _children_of(proc.pid)
    shm_before = set(os.listdir("/dev/shm"))
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    if sig == signal.SIGINT:
        assert proc.returncode == 130 and "interrupted" in err
    # no worker outlives the run, and nothing is left in /dev/shm (no semaphores: workers talk over pipes)
    assert workers and _wait_for(lambda: not any(Path(f"/proc/{w}").exists() for w in workers), 10)
    assert not [n for n in set(os.listdir("/dev/shm")) - shm_before if n.startswith("sem.")]
    assert not [n for n in os.listdir("/dev/shm") if n.startswith("sem.mp-")]
    r = generate(run_cli, out, workers=2)
    assert "60 frames in 3 episodes" in r.stdout
    m = read_manifest(out)
    assert m["complete"] and sorted(s["episode"] for s in m["shards"]) == [0, 1, 2]
    assert content(out) == content(reference)
    assert not list(out.glob(".*.tmp"))


def test_other_options_refuse_to_continue(reference, run_cli, tmp_path):
    out = tmp_path / "ds"
    generate(run_cli, out)
    r = run_cli("generate", "--out", out, *SMALL, "--seed", "5")
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "other options (seed differ)" in r.stderr


def test_corrupt_shard_is_named(reference, run_cli, tmp_path):
    import shutil
    broken = tmp_path / "broken"
    shutil.copytree(reference, broken)
    shard = broken / "shard-000001.parquet"
    shard.write_bytes(shard.read_bytes()[: shard.stat().st_size // 2])
    with pytest.raises(DatasetError, match="shard-000001.parquet is corrupt or truncated"):
        ShardReader(shard, Dataset(broken).declaration)
    with pytest.raises(DatasetError, match="shard-000001.parquet is damaged"):
        Dataset(broken).reader(Dataset(broken).shards[1])   # the manifest's size does not match
    r = run_cli("stats", broken)
    assert r.returncode == 2 and "shard-000001.parquet" in r.stderr and "Traceback" not in r.stderr


def test_resume_regenerates_a_damaged_shard(reference, run_cli, tmp_path):
    import shutil
    out = tmp_path / "ds"
    shutil.copytree(reference, out)
    shard = out / "shard-000002.parquet"
    shard.write_bytes(shard.read_bytes()[:-100])                 # truncated after the manifest listed it
    r = generate(run_cli, out, workers=1)
    assert "recording episode 2 again" in r.stdout + r.stderr and "60 frames in 3 episodes" in r.stdout
    assert content(out) == content(reference)
    r = run_cli("stats", out, "--out", tmp_path / "s")
    assert r.returncode == 0, r.stderr


def test_a_manifest_that_is_not_json_gets_one_line(reference, run_cli, tmp_path):
    import shutil
    out = tmp_path / "ds"
    shutil.copytree(reference, out)
    (out / "manifest.json").write_bytes(b"\xff\xfe not utf-8 \x00")
    for verb in (["stats", str(out)], ["evaluate", "--data", str(out), "--model", str(out / "manifest.json")],
                 ["generate", "--out", str(out), *SMALL]):
        r = run_cli(*verb)
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, verb


def test_a_version_1_dataset_or_checkpoint_is_refused_in_one_line(run_cli, tmp_path):
    """Format version 1 (drivestudio 0.1, before worlds were declared) is no longer read: a dataset or a checkpoint
    of it is refused in one line, exit 2, saying what to do, and nothing is written."""
    import shutil

    import torch
    old = tmp_path / "old"
    shutil.copytree(Path(__file__).parent / "fixtures" / "highway-10", old)
    manifest = json.loads((old / "manifest.json").read_text())
    (old / "manifest.json").write_text(json.dumps({**manifest, "version": 1}))
    r = run_cli("stats", old, "--out", tmp_path / "s")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "format version 1 (drivestudio 0.1), which is no longer read; generate it again" in r.stderr
    assert not (tmp_path / "s").exists()
    torch.save({"format": "drivestudio-perception", "version": 1, "spec": {}, "state_dict": {}}, tmp_path / "m.pt")
    r = run_cli("evaluate", "--data", Path(__file__).parent / "fixtures" / "highway-10", "--model", tmp_path / "m.pt",
                "--out", tmp_path / "e")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "checkpoint of format version 1 (drivestudio 0.1), which is no longer read; train it again" in r.stderr


@pytest.mark.parametrize("args, message", [
    (["--frames", "0"], "argument --frames: must be an integer from 1"),
    (["--lanes", "2,7"], "--lanes must list lane counts from 1 to 4"),
    (["--cars", "x"], "expected N or A-B"),
    (["--tracks", "nowhere"], "unknown track preset 'nowhere'"),
])
def test_bad_options_get_one_line(run_cli, tmp_path, args, message):
    r = run_cli("generate", "--out", tmp_path / "x", *args)
    assert r.returncode == 2 and message in r.stderr and r.stderr.count("\n") == 1


def test_stats_reports_coverage_and_writes_histograms(reference, run_cli, tmp_path):
    r = run_cli("stats", reference, "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    assert "| frames | 60 |" in r.stdout and "lane changes" in r.stdout
    summary = json.loads((tmp_path / "stats.json").read_text())
    assert summary["frames"] == 60 and summary["episodes"] == 3
    shares = summary["share_in_lane_only"] + summary["share_on_marking_only"] + summary["share_overlap"]
    assert shares == pytest.approx(1.0, abs=0.01)  # every frame is in at least one system
    assert (tmp_path / "histograms.png").stat().st_size > 1000 and (tmp_path / "hist-dist_MM.png").exists()


@pytest.mark.long
def test_ray_backend_produces_the_same_shards(reference, run_cli, tmp_path):
    pytest.importorskip("ray", reason="the Ray backend is optional: pip install 'drivestudio[cluster]'")
    out = tmp_path / "ray"
    # the local Ray instance's session folder in a temporary of the test's own, not left in /tmp/ray (short: Ray's
    # socket paths must stay under 108 bytes)
    temp = tempfile.mkdtemp(prefix="ray-", dir="/tmp")
    try:
        r = generate(run_cli, out, "--backend", "ray", check=False, env={"RAY_TMPDIR": temp})
    finally:
        shutil.rmtree(temp, ignore_errors=True)
    assert r.returncode == 0, r.stderr
    assert content(out) == content(reference)


def test_resuming_over_a_shard_of_another_world_is_refused(run_cli, tmp_path):
    """A manifest whose entry names a sidewalk shard with that shard's size and checksum: the shard is whole, so
    only its columns tell; continuing would report success and leave an unreadable dataset."""
    hw, sw = tmp_path / "hw", tmp_path / "sw"
    gen = ["generate", "--workers", "1"]
    hw_args = ["--out", str(hw), "--frames", "20", "--episode-frames", "10", "--tracks", "oval", "--cars", "0-0",
               "--set", "camera.width=70", "--set", "camera.height=52"]
    assert run_cli(*gen, *hw_args).returncode == 0
    assert run_cli(*gen, "--world", "sidewalk", "--out", sw, "--frames", "10", "--episode-frames", "10").returncode == 0
    manifest = json.loads((hw / "manifest.json").read_text())
    foreign = json.loads((sw / "manifest.json").read_text())["shards"][0]
    shutil.copy(sw / foreign["file"], hw / manifest["shards"][0]["file"])
    manifest["shards"][0].update(size=foreign["size"], sha256=foreign["sha256"], frames=foreign["frames"])
    manifest["complete"] = False
    (hw / "manifest.json").write_text(json.dumps(manifest))
    before = {p.name: p.read_bytes() for p in hw.iterdir() if p.is_file()}
    r = run_cli(*gen, *hw_args)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "does not have the columns of a highway dataset" in r.stderr and "give a new --out" in r.stderr
    assert {p.name: p.read_bytes() for p in hw.iterdir() if p.is_file()} == before


@pytest.mark.parametrize("given, stored", [("jpeg:40", ("jpeg", 40)), ("jpeg", ("jpeg", 95))])
def test_jpeg_frames_are_stored_at_the_quality_asked(run_cli, tmp_path, given, stored):
    """--encoding jpeg[:QUALITY]: the manifest records the format and the quality, and the frames are stored as
    JPEG."""
    out = tmp_path / given.replace(":", "-")
    r = run_cli("generate", "--out", out, "--frames", "10", "--episode-frames", "10", "--workers", 1,
                "--encoding", given, "--set", "camera.width=70", "--set", "camera.height=52")
    assert r.returncode == 0, r.stderr
    config = read_manifest(out)["config"]
    assert (config["encoding"], config["quality"]) == stored
    ds = Dataset(out)
    raw = pq.read_table(out / ds.shards[0].file).column("image_front")[0].as_py()
    assert raw[:3] == b"\xff\xd8\xff"      # a JPEG's start-of-image marker


@pytest.mark.parametrize("given", ["png:90", "gif", "jpeg:0", "jpeg:101", "jpeg:x"])
def test_a_bad_encoding_is_one_line_before_any_work(run_cli, tmp_path, given):
    r = run_cli("generate", "--out", tmp_path / "d", "--frames", "10", "--encoding", given)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--encoding" in r.stderr, r.stderr
    assert not (tmp_path / "d").exists()
