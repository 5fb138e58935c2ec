"""`drivestudio recipe --quick`: from nothing to a leaderboard of every aggregation round beside the oracle, through
the verbs a user would run (generate, train, aggregate with its benchmark), on a one-route suite."""
import json
import subprocess
import sys

import pytest

from drivestudio.commands.recipe import FULL


@pytest.mark.slow   # about 80 s: every step of the recipe at its smallest (run with pytest -m slow)
def test_the_recipe_goes_from_nothing_to_the_leaderboard(tmp_path):
    suite = tmp_path / "tiny.json"
    suite.write_text(json.dumps({"name": "tiny", "routes": [{"name": "oval-1l", "track": "oval", "lanes": 1,
                                                             "cars": 0, "seed": 1, "seconds": 5}]}))
    out = tmp_path / "recipe"
    r = subprocess.run([sys.executable, "-m", "drivestudio", "recipe", "--quick", "--out", str(out), "--suite",
                        str(suite), "--workers", "1"], capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    board = json.loads((out / "aggregation" / "benchmark" / "leaderboard.json").read_text())
    specs = [m["spec"] for m in board["models"]]
    assert specs[0] == "oracle" and specs[1].endswith("mobilenet.pt") and specs[2].endswith("round-1/model.pt")
    assert all(m["overall"]["route_completion"] > 0 for m in board["models"])
    commands = (out / "commands.txt").read_text().splitlines()
    assert [c.split()[1] for c in commands] == ["generate", "train", "aggregate"]
    # the first training and the rounds both weigh the decisive frames by the recipe's emphasis
    assert all(f"--emphasis {FULL.emphasis}" in c for c in commands[1:]) and FULL.emphasis > 1
    state = json.loads((out / "aggregation" / "aggregation.json").read_text())
    assert state["complete"] and len(state["rounds"]) == 1 and state["benchmark"]["suite"] == "tiny"
    assert "recipe done in" in r.stdout
