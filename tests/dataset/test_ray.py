"""Dataset generation on a real Ray cluster: a local head with two worker slots (`ray start --head`), episodes as Ray
tasks through `drivestudio generate --backend ray`, and the same dataset as a local run of the same seed, shard for
shard, byte for byte (docs/scaling.md)."""
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from perception.shards import Dataset

ray = pytest.importorskip("ray", reason="Ray is not installed: pip install 'drivestudio[cluster]'")

pytestmark = pytest.mark.slow

RAY = str(Path(sys.executable).with_name("ray"))
SMALL = ["--frames", "100", "--episode-frames", "10", "--tracks", "oval,hairpins", "--lanes", "2,3", "--cars", "6",
         "--set", "camera.width=140", "--set", "camera.height=105", "--seed", "7"]
# keep Ray on the loopback interface (by default it advertises the machine's own address, even for a local head)
LOOPBACK = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_USAGE_STATS_ENABLED": "0"}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def cluster():
    """A Ray head on this machine with two CPUs (two tasks at a time); stopped afterwards, also on failure."""
    temp = Path(tempfile.mkdtemp(prefix="ray-", dir="/tmp"))   # short: Ray's socket paths must stay < 108 bytes
    port = _free_port()
    # a home of the test's own: a token left in ~/.ray/auth_token by another cluster would be sent to ours, refused
    env = {**os.environ, **LOOPBACK, "HOME": str(temp)}
    env.pop("RAY_ADDRESS", None)
    env.pop("RAY_AUTH_TOKEN", None)
    cmd = [RAY, "start", "--head", "--node-ip-address", "127.0.0.1", "--port", str(port), "--num-cpus", "2",
           "--temp-dir", str(temp), "--include-dashboard=false", "--disable-usage-stats",
           "--object-store-memory", str(100 * 2**20)]
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=180)
        assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
        yield {**env, "RAY_ADDRESS": f"127.0.0.1:{port}"}
    finally:
        subprocess.run([RAY, "stop", "--force"], capture_output=True, env=env, timeout=120)
        shutil.rmtree(temp, ignore_errors=True)


def generate(out: Path, env: dict, *extra: str) -> subprocess.CompletedProcess:
    r = subprocess.run([sys.executable, "-m", "drivestudio", "generate", "--out", str(out), *SMALL,
                        *extra], capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return r


def test_ray_generation_equals_a_local_run_of_the_same_seed(cluster, tmp_path):
    on_ray = tmp_path / "ray"
    generate(on_ray, cluster, "--backend", "ray")
    local = tmp_path / "local"
    generate(local, {k: v for k, v in cluster.items() if k != "RAY_ADDRESS"}, "--workers", "2")

    a, b = (json.loads((d / "manifest.json").read_text()) for d in (on_ray, local))
    assert a["complete"] and b["complete"] and a["frames"] == b["frames"] == 100
    assert len(a["shards"]) == 10
    assert a["config"] == b["config"] and a["world"] == b["world"]
    # the same episodes, the same bytes: every shard's size and SHA-256 agree
    assert [(s["episode"], s["frames"], s["size"], s["sha256"]) for s in a["shards"]] == \
           [(s["episode"], s["frames"], s["size"], s["sha256"]) for s in b["shards"]]
    # and the decoded content (images and labels) reads the same through the readers
    da, db = Dataset(on_ray), Dataset(local)
    for sa, sb in zip(da.shards, db.shards):
        assert pq.read_table(on_ray / sa.file).equals(pq.read_table(local / sb.file))
    images_a, rec_a = da.reader(da.shards[3]).row(4)
    images_b, rec_b = db.reader(db.shards[3]).row(4)
    assert (images_a[0] == images_b[0]).all() and rec_a == rec_b


def test_a_ray_run_continues_a_partial_dataset(cluster, tmp_path):
    """Resuming works across backends: half the episodes locally, the rest as Ray tasks, same bytes."""
    out = tmp_path / "mixed"
    generate(out, {k: v for k, v in cluster.items() if k != "RAY_ADDRESS"}, "--workers", "1")
    manifest = json.loads((out / "manifest.json").read_text())
    reference = {s["episode"]: s["sha256"] for s in manifest["shards"]}
    for s in manifest["shards"][5:]:          # forget the second half: as if the run had been killed
        (out / s["file"]).unlink()
    manifest["shards"], manifest["complete"] = manifest["shards"][:5], False
    manifest["frames"] = sum(s["frames"] for s in manifest["shards"])
    (out / "manifest.json").write_text(json.dumps(manifest))
    generate(out, cluster, "--backend", "ray")
    again = json.loads((out / "manifest.json").read_text())
    assert again["complete"] and {s["episode"]: s["sha256"] for s in again["shards"]} == reference


def test_an_unreachable_cluster_fails_in_one_line(tmp_path):
    env = {**os.environ, **LOOPBACK, "RAY_ADDRESS": f"127.0.0.1:{_free_port()}"}
    r = subprocess.run([sys.executable, "-m", "drivestudio", "generate", "--out", str(tmp_path / "x"), *SMALL,
                        "--backend", "ray"], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode != 0 and "Traceback" not in r.stderr
