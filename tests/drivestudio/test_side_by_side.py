"""The recipe's runner of its members' trainings (drivestudio/commands/recipe_steps.py's run_side_by_side, on
drivestudio/pool.py): real child processes of the `drivestudio` command; progress read from their logs; a child
that fails stops the others and names itself. And the recipe's rule for a benchmark done before
(drivestudio/commands/recipe.py: done_before)."""
import json
import os
import time

import pytest

from drivestudio.commands.recipe_steps import done_before, run_side_by_side
from drivestudio.errors import RunError
from drivestudio.pool import progress
from drivestudio.worlds.highway.benchmark import DEFAULT_SUITE, load_suite


def test_progress_is_the_last_count_a_bar_wrote(tmp_path):
    log = tmp_path / "a.log"
    assert progress(log) == "-"                                    # not written yet
    log.write_bytes(b"loading\n")
    assert progress(log) == "-"
    log.write_bytes(b"mobilenet:  1%| | 62/6000 [00:30<..]\rmobilenet:  3%| | 196/6000 [01:00<..]\r")
    assert progress(log) == "196/6000"


def test_all_children_run_and_write_their_logs(tmp_path):
    logs = [tmp_path / "a.log", tmp_path / "b.log"]
    run_side_by_side([["render", "--help"], ["probe", "--help"]], logs)
    assert "drivestudio render" in logs[0].read_text() and "drivestudio probe" in logs[1].read_text()


def test_a_child_that_fails_stops_the_others_and_is_named(tmp_path):
    logs = [tmp_path / "slow.log", tmp_path / "bad.log"]
    t0 = time.perf_counter()
    with pytest.raises(RunError, match=r"bad\.log: exit status 2: .*missing\.json"):
        run_side_by_side([["generate", "--out", str(tmp_path / "g"), "--frames", "1000000", "--workers", "1"],
                          ["probe", str(tmp_path / "missing.json")]], logs)
    assert time.perf_counter() - t0 < 60          # a million frames were not waited for: the generation was stopped


@pytest.mark.long
def test_a_child_after_another_starts_once_that_one_has_succeeded_and_never_after_a_failure(tmp_path):
    logs = [tmp_path / "bad.log", tmp_path / "after-bad.log"]
    with pytest.raises(RunError, match=r"bad\.log: exit status 2"):
        run_side_by_side([["probe", str(tmp_path / "missing.json")], ["render", "--help"]], logs, after=[None, 0])
    assert logs[0].exists() and not logs[1].exists()              # never started
    logs = [tmp_path / "first.log", tmp_path / "second.log"]
    run_side_by_side([["render", "--help"], ["probe", "--help"]], logs, after=[None, 0])
    assert "drivestudio render" in logs[0].read_text() and "drivestudio probe" in logs[1].read_text()
    assert logs[0].stat().st_mtime <= logs[1].stat().st_ctime


def test_a_child_can_only_follow_an_earlier_one(tmp_path):
    logs = [tmp_path / "a.log", tmp_path / "b.log"]
    for after in ([1, None], [0, None], [None, 1]):
        with pytest.raises(ValueError, match="after an earlier one"):
            run_side_by_side([["render", "--help"], ["probe", "--help"]], logs, after=after)
    assert not logs[0].exists() and not logs[1].exists()


def test_a_benchmark_is_done_before_only_for_the_same_suite_and_newer_than_every_model(tmp_path):
    model = tmp_path / "m.pt"
    model.write_bytes(b"x")
    bench = tmp_path / "benchmark"
    assert not done_before(bench, "default", [model])             # none yet
    bench.mkdir()
    board = bench / "leaderboard.json"
    board.write_text(json.dumps({"suite": {"sha256": load_suite(DEFAULT_SUITE).sha256}}))
    os.utime(model, (time.time() - 60, time.time() - 60))
    assert done_before(bench, "default", [model])
    assert not done_before(bench, str(DEFAULT_SUITE.parent / "design.json"), [model])   # another suite
    os.utime(model, (time.time() + 60, time.time() + 60))
    assert not done_before(bench, "default", [model])             # the model changed since


def test_sigterm_to_the_runner_stops_its_children(tmp_path):
    """A recipe stopped with SIGTERM (a scheduler's, a CI's timeout) leaves no training running behind it."""
    import signal
    import subprocess
    import sys

    out = tmp_path / "gen-stopped"
    code = ("from pathlib import Path\nfrom drivestudio.commands.recipe_steps import run_side_by_side\n"
            f"run_side_by_side([['generate', '--out', {str(out)!r}, '--frames', '1000000', '--workers', '1']], "
            f"[Path({str(tmp_path / 'g.log')!r})])\n")
    def running() -> set[int]:
        """The processes whose command line names the output folder: the runner and its child."""
        found = subprocess.run(["pgrep", "-f", str(out)], capture_output=True, text=True).stdout
        return set(map(int, found.split()))

    runner = subprocess.Popen([sys.executable, "-c", code])
    deadline = time.monotonic() + 60
    while not running() - {runner.pid} and time.monotonic() < deadline:
        time.sleep(0.1)
    assert running() - {runner.pid}                                 # the child is running
    runner.send_signal(signal.SIGTERM)
    assert runner.wait(timeout=60) != 0
    deadline = time.monotonic() + 10
    while running() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not running()                                            # none left
