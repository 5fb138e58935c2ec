"""The benchmark suite (`python -m bench`, bench/run_all.py) runs benches and prints their figures as one table with
the machine and the versions; the full run (10-15 minutes) is not a test."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def test_the_quick_suite_prints_a_table_of_figures(tmp_path):
    doc_before = (REPO / "docs" / "benchmarks.md").read_text()
    out = tmp_path / "results.json"
    r = subprocess.run([sys.executable, "-m", "bench", "--quick", "--only", "bridge,render", "--no-write",
                        "--json", str(out)], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    lines = r.stdout.splitlines()
    assert any(ln.startswith("| bench | figure | measured | target | run") for ln in lines)
    rows = [ln for ln in lines if ln.startswith("| ") and not ln.startswith("| bench |")]
    assert {ln.split(" | ")[0][2:] for ln in rows} == {"render", "bridge", "bridge-sidewalk"}
    assert any("frames/s" in ln for ln in rows if ln.startswith("| render |"))
    assert any("median" in ln and "µs" in ln for ln in rows if ln.startswith("| bridge |"))
    assert "lock-step round trip" in r.stdout          # each bench's own printed output is kept
    assert "cores" in r.stdout and "torch " in r.stdout and "pybullet " in r.stdout and "highway-env " in r.stdout
    results = json.loads(out.read_text())
    assert set(results["benches"]) == {"render", "bridge", "bridge-sidewalk"}
    assert results["machine"]["cores"] and results["versions"]["python"]
    assert all(e["status"] == "ok" and e["figures"] for e in results["benches"].values())
    assert (REPO / "docs" / "benchmarks.md").read_text() == doc_before   # --no-write writes nothing


def test_an_unknown_bench_is_refused_in_one_line():
    r = subprocess.run([sys.executable, "-m", "bench", "--only", "nosuch", "--no-write"], cwd=REPO,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "no bench nosuch" in r.stderr and "Traceback" not in r.stderr


def test_the_table_goes_between_the_markers_and_nowhere_else(tmp_path):
    sys.path.insert(0, str(REPO))
    from bench.run_all import BEGIN, END, write_doc

    doc = tmp_path / "benchmarks.md"
    doc.write_text("# Benchmarks\n\nintro\n\n| a | b |\n|---|---|\n\n## Rendering\nrest\n")
    write_doc("TABLE-ONE\n", doc)
    text = doc.read_text()
    assert text.index("## The suite") < text.index(BEGIN) < text.index("TABLE-ONE") < text.index(END) < \
        text.index("## Rendering") and text.startswith("# Benchmarks\n\nintro\n\n| a | b |")
    write_doc("TABLE-TWO\n", doc)
    again = doc.read_text()
    assert "TABLE-ONE" not in again and again.count(BEGIN) == 1 and again.count("## The suite") == 1
    assert again.replace("TABLE-TWO", "TABLE-ONE") == text


@pytest.mark.slow
def test_the_highway_env_comparison_runs_or_says_why_not(tmp_path):
    out = tmp_path / "hw.json"
    r = subprocess.run([sys.executable, "bench/bench_highway_env.py", "--steps", "20", "--rounds", "2", "--json",
                        str(out)], cwd=REPO, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-2000:]
    result = json.loads(out.read_text())
    if result["measured"]:
        assert result["ratio"] > 0 and len(result["rounds"]) == 2 and "ratio ours/theirs" in r.stdout
        assert result["theirs"]["config"]["lanes_count"] == 3 and result["theirs"]["config"]["vehicles_count"] == 12
        assert result["theirs"]["frame"] == [210, 280, 3] and result["ours"]["frame"] == [210, 280, 3]
    else:
        assert r.stdout.strip().count("\n") == 0 and "not measured" in r.stdout


def test_every_benchmark_of_bench_is_in_the_suite():
    sys.path.insert(0, str(REPO))
    from bench.run_all import BENCHES, uncovered

    assert uncovered() == []
    assert all((REPO / "bench" / b.script).exists() for b in BENCHES)


def test_the_whole_commands_rows_give_minutes_the_target_and_the_recipes_driver():
    sys.path.insert(0, str(REPO))
    from bench.run_all import rows_commands

    recipe = {"argv": ["recipe", "--extended", "--out", "out/recipe"], "status": 0, "minutes": 41.26,
              "cpu_minutes": 80.4, "target_minutes": 40.0,
              "random_suite": {"drivers": [{"percent_of_oracle-extended": 96.7, "collisions": 1, "km": 51.1}]}}
    demo = {"argv": ["demo", "--out", "out/demo"], "status": 3, "minutes": 0.5, "cpu_minutes": 1.0,
            "target_minutes": None}
    rows = rows_commands({"machine": {"cores": 2}, "commands": [recipe, demo]})
    assert rows[0] == ("`drivestudio recipe --extended` from a fresh clone, 2 cores",
                       "**41.3 minutes** (80 CPU minutes); its driver 96.7 % of the extended oracle on the random "
                       "suite, 1 collisions in 51.1 km", "<= 40 minutes (issue 48)")
    assert rows[1] == ("`drivestudio demo` from a fresh clone, 2 cores", "failed (exit 3)", "")
