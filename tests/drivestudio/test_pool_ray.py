"""The pool's Ray backend (drivestudio/pool.py) for the benchmark and the study, on a real local Ray head with two
worker slots (tests/dataset/test_ray.py's): the benchmark's rows as Ray tasks equal a local run's; the study's
jobs keep their order on the cluster, and a failure is one line (docs/scaling.md)."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.dataset.test_ray import LOOPBACK, _free_port
from tests.dataset.test_ray import cluster as cluster  # the fixture: a local Ray head, stopped afterwards

pytest.importorskip("ray", reason="Ray is not installed: pip install 'drivestudio[cluster]'")

pytestmark = pytest.mark.slow

TIMING = ("wall_s", "loop_rate_hz")   # measured, not driven: they differ between any two runs


def benchmark(out: Path, suite: Path, env: dict, *extra: str) -> dict:
    r = subprocess.run([sys.executable, "-m", "drivestudio", "benchmark", "--model", "oracle", "--suite", str(suite),
                        "--clips", "0", "--out", str(out), *extra], capture_output=True, text=True,
                       env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    board = json.loads((out / "leaderboard.json").read_text())
    board.pop("run")
    for model in board["models"]:
        for route in model["routes"]:
            for key in TIMING:
                route.pop(key, None)
    return board


def test_a_benchmark_on_ray_gives_the_rows_of_a_local_run(cluster, tmp_path):
    suite = tmp_path / "tiny.json"
    suite.write_text(json.dumps({"name": "tiny", "routes": [
        {"name": "oval-1l", "track": "oval", "lanes": 1, "cars": 0, "seed": 1, "seconds": 5},
        {"name": "oval-2l", "track": "oval", "lanes": 2, "cars": 4, "seed": 2, "seconds": 5}]}))
    on_ray = benchmark(tmp_path / "ray", suite, cluster, "--backend", "ray")
    local = benchmark(tmp_path / "local", suite, {k: v for k, v in cluster.items() if k != "RAY_ADDRESS"},
                      "--workers", "2")
    assert [r["route"] for r in on_ray["models"][0]["routes"]] == ["oval-1l", "oval-2l"]
    assert on_ray == local


STUDY_JOBS = """import sys
from pathlib import Path
from drivestudio.worlds.sidewalk.study import Job, run_jobs
d = Path(sys.argv[1])
stand_in = sys.argv[2]
jobs = [Job("a", ["a", 0.5, "-", d]), Job("b", ["b", 0.1, "a", d], after=("a",)), Job("c", ["c", 0.1, "-", d])]
if sys.argv[3] == "fail":
    jobs = [Job("a", ["a", 0.1, "missing", d]), Job("b", ["b", 0.1, "-", d], after=("a",))]
run_jobs(jobs, 2, d / "logs", command=(sys.executable, "-c", stand_in), backend="ray")
"""


def test_the_studys_jobs_on_ray_keep_their_order_and_fail_in_one_line(cluster, tmp_path):
    from tests.sidewalk.test_study import STAND_IN
    r = subprocess.run([sys.executable, "-c", STUDY_JOBS, str(tmp_path), STAND_IN, "ok"], capture_output=True,
                       text=True, env=cluster, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    stamp = {p.name: float(p.read_text()) for p in tmp_path.glob("*.*") if p.suffix in (".start", ".end")}
    assert stamp["b.start"] >= stamp["a.end"] and {"a.end", "b.end", "c.end"} <= set(stamp)
    assert "$ drivestudio b 0.1 a" in r.stdout and (tmp_path / "logs" / "b.log").exists()
    for p in tmp_path.glob("*.*"):
        p.unlink()
    r = subprocess.run([sys.executable, "-c", STUDY_JOBS, str(tmp_path), STAND_IN, "fail"], capture_output=True,
                       text=True, env=cluster, timeout=300)
    assert r.returncode != 0 and "a failed: see" in r.stderr and not (tmp_path / "b.start").exists()


def test_a_study_on_an_unreachable_cluster_fails_in_one_line(tmp_path):
    env = {**os.environ, **LOOPBACK, "RAY_ADDRESS": f"127.0.0.1:{_free_port()}"}
    r = subprocess.run([sys.executable, "-m", "drivestudio", "study", "--quick", "--out", str(tmp_path / "s"),
                        "--backend", "ray"], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 1 and "Traceback" not in r.stderr and "no Ray cluster answers" in r.stderr, r.stderr
