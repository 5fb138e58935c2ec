"""`drivestudio recipe --quick`: from nothing to a leaderboard through the verbs a user would run, on a one-route
suite: the ensemble recipe (generate, members trained side by side, their ensemble, the benchmark) and the single
network's (generate, train, aggregate with its benchmark)."""
import json
import subprocess
import sys

import pytest
import torch

from drivestudio.commands.recipe import FULL, QUICK
from drivestudio.commands.recipe_extended import EXTENDED, REAR_TARGETS, Extended
from perception.shards import Dataset


def tiny_suite(tmp_path):
    suite = tmp_path / "tiny.json"
    suite.write_text(json.dumps({"name": "tiny", "routes": [{"name": "oval-1l", "track": "oval", "lanes": 1,
                                                             "cars": 0, "seed": 1, "seconds": 5}]}))
    return suite


def recipe(tmp_path, *options):
    out = tmp_path / "recipe"
    r = subprocess.run([sys.executable, "-m", "drivestudio", "recipe", "--quick", "--out", str(out), "--suite",
                        str(tiny_suite(tmp_path)), "--workers", "1", *options], capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "recipe done in" in r.stdout
    return out, r


@pytest.mark.slow   # about 90 s: every step of the recipe at its smallest (run with pytest -m slow)
def test_the_recipe_trains_members_side_by_side_and_benchmarks_their_ensemble(tmp_path):
    out, _ = recipe(tmp_path)
    board = json.loads((out / "benchmark" / "leaderboard.json").read_text())
    specs = [m["spec"] for m in board["models"]]
    members = [f"member-{k}.pt" for k in range(QUICK.members)]
    assert specs[0] == "oracle" and [s.rsplit("/", 1)[-1] for s in specs[1:-1]] == members
    assert specs[-1].endswith(f"ensemble.pt@pass_memory={FULL.pass_memory:g}")
    assert all(m["overall"]["route_completion"] > 0 for m in board["models"])
    # members from different seeds: different weights; the ensemble holds each member's
    weights = [torch.load(out / m, map_location="cpu", weights_only=False)["state_dict"] for m in members]
    key = next(k for k, v in weights[0].items() if v.dtype.is_floating_point and v.numel() > 100)
    assert not torch.equal(weights[0][key], weights[1][key])
    ensemble = torch.load(out / "ensemble.pt", map_location="cpu", weights_only=False)
    assert [m["source"].rsplit("/", 1)[-1] for m in ensemble["spec"]["options"]["members"]] == members
    commands = (out / "commands.txt").read_text().splitlines()
    assert [c.split()[1] for c in commands] == ["generate", "train", "train", "ensemble", "benchmark"]
    assert [c.split("--seed ")[1] for c in commands[1:3]] == ["0", "1"]
    assert all(f"--set emphasis={FULL.emphasis}" in c for c in commands[1:3]) and FULL.emphasis > 1
    # run again: every step is found done, nothing is trained or driven again
    _, again = recipe(tmp_path)
    assert "the benchmark: done before" in again.stdout and "nothing to do" in (out / "member-0.log").read_text()


@pytest.mark.slow   # about 80 s
def test_the_single_network_recipe_runs_aggregation_rounds_all_in_the_renderer_it_names(tmp_path):
    out, _ = recipe(tmp_path, "--set", "members=1", "--set", "rounds=1", "--set", "renderer=tiny")
    board = json.loads((out / "aggregation" / "benchmark" / "leaderboard.json").read_text())
    specs = [m["spec"] for m in board["models"]]
    assert specs[0] == "oracle" and specs[1].endswith("mobilenet.pt") and specs[2].endswith("round-1/model.pt")
    commands = (out / "commands.txt").read_text().splitlines()
    assert [c.split()[1] for c in commands] == ["generate", "train", "aggregate"]
    # TinyRenderer draws the expert's frames, the round's and the benchmark's
    assert "--set renderer=tiny" in commands[0] and board["run"]["renderer"] == "tiny"
    assert Dataset(out / "data").renderers == Dataset(out / "aggregation" / "round-1" / "data").renderers == ("tiny",)
    assert all(f"--set emphasis={FULL.emphasis}" in c for c in commands[1:])
    state = json.loads((out / "aggregation" / "aggregation.json").read_text())
    assert state["complete"] and len(state["rounds"]) == 1 and state["benchmark"]["suite"] == "tiny"


@pytest.mark.slow   # about 2 minutes
def test_the_extended_recipe_trains_forward_and_rear_networks_and_a_round_each(tmp_path):
    out, _ = recipe(tmp_path, "--extended", "--set", "rear_members=2")
    board = json.loads((out / "benchmark" / "leaderboard.json").read_text())
    specs = [m["spec"] for m in board["models"]]
    assert specs[:2] == ["oracle", "oracle-extended"]
    assert specs[2].endswith(f"ensemble.pt@pass_memory={EXTENDED.pass_memory:g},rear_memory={EXTENDED.rear_memory:g}")
    assert "lookout" in board["models"][2]["model"]
    ensemble = torch.load(out / "ensemble.pt", map_location="cpu", weights_only=False)
    sources = [m["source"] for m in ensemble["spec"]["options"]["members"]]
    assert [s.split("/")[-3:] for s in sources[:2]] == [[f"aggregation-{k}", "round-1", "model.pt"] for k in (0, 1)]
    assert [s.rsplit("/", 1)[-1] for s in sources[2:]] == ["rear.pt", "rear-1.pt"]
    assert set(ensemble["spec"]["outputs"]) >= {"dist_LB", "closing_RB", "dist_MM"}
    commands = (out / "commands.txt").read_text().splitlines()
    assert [c.split()[1] for c in commands] == ["generate", "generate", "train", "train", "train", "train",
                                                "aggregate", "aggregate", "ensemble", "benchmark"]
    assert f"--set side_views=true --lanes 1,2,3 --cars {EXTENDED.cars} " in commands[0]
    assert f"--set side_views=true --lanes 1,2,3,4 --cars {EXTENDED.cars} " in commands[1]
    assert EXTENDED.cars == "12-60" and all(f"--set cars={EXTENDED.cars}" in c for c in commands[6:8])
    assert ensemble["spec"]["input"]["inset"] == "mirror+sides"
    assert [c.split("--seed ")[1].split()[0] for c in commands[2:6]] == ["0", "1", "0", "2"]   # rear: seeds 0, 2
    assert all(f"--targets {REAR_TARGETS}" in c and "emphasis" not in c for c in commands[4:6])
    assert all("data-mirror-4lanes" in c for c in commands[4:6])
    assert all(f"--set emphasis={EXTENDED.emphasis}" in c for c in commands[2:4])
    assert all(f"--set emphasis={EXTENDED.emphasis}" in c and f"--set beta={EXTENDED.beta}" in c for c in commands[6:8])
    # every dataset and network fingerprinted, as `stats --fingerprint` and the checkpoint's stored digest say
    prints = json.loads((out / "fingerprints.json").read_text())
    assert {"data-mirror", "data-mirror-4lanes", "aggregation-0/round-1/data"} <= set(prints["datasets"])
    merged = prints["datasets"]["aggregation-0/round-1/merged"]   # its frames are its sources': labels alone
    assert merged["images"] is None and merged["frames"] > prints["datasets"]["data-mirror"]["frames"]
    assert {"forward-0.pt", "forward-1.pt", "rear.pt", "rear-1.pt", "aggregation-1/round-1/model.pt",
            "ensemble.pt"} <= set(prints["networks"])
    subprocess.run([sys.executable, "-m", "drivestudio", "stats", str(out / "data-mirror"), "--fingerprint",
                    "--out", str(tmp_path / "stats")], capture_output=True, text=True, check=True)
    assert json.loads((tmp_path / "stats" / "stats.json").read_text())["fingerprint"] == \
        prints["datasets"]["data-mirror"]
    assert prints["networks"]["rear.pt"] == torch.load(out / "rear.pt", weights_only=False)["state_sha256"]


def _sized(*argv):
    from drivestudio import cli
    from drivestudio.commands.recipe import recipe_config
    return recipe_config(cli.build_parser().parse_args(["recipe", *argv]))


def test_the_recipe_sizes_refuse_rounds_of_an_ensemble_but_not_of_the_extended_recipe():
    from core.settings import SettingError
    from drivestudio.commands.recipe import Size
    from drivestudio.errors import UsageError
    assert _sized() == FULL
    assert _sized("--extended", "--set", "rounds=2", "--set", "members=3") == Extended(rounds=2, members=3)
    assert isinstance(_sized("--extended", "--quick"), Extended)
    with pytest.raises(UsageError, match="rounds=2 needs members=1"):
        _sized("--set", "rounds=2")
    assert isinstance(_sized("--set", "rounds=2", "--set", "members=1"), Size)
    assert _sized("--extended", "--set", "rear_members=2") == Extended(rear_members=2)
    with pytest.raises(UsageError, match="rear_members=2: a setting of the extended recipe; give --extended too"):
        _sized("--set", "rear_members=2")
    assert Extended().side_views and _sized("--extended").side_views
    assert _sized("--extended", "--set", "side_views=false") == Extended(side_views=False)
    assert _sized("--extended", "--set", "renderer=tiny") == Extended(renderer="tiny")
    with pytest.raises(SettingError, match="renderer"):
        _sized("--set", "renderer=pov-ray")
    with pytest.raises(UsageError, match="side_views=false: a setting of the extended recipe"):
        _sized("--set", "side_views=false")


def test_the_recipes_renderer_reaches_generate_and_the_benchmark_and_the_default_reads_as_before():
    from drivestudio.commands.recipe_steps import renderer_argv, training_plan
    tiny = Extended(renderer="tiny")
    assert training_plan(tiny)[-2:] == ["--set", "renderer=tiny"] and renderer_argv(tiny, "--renderer") == [
        "--renderer", "tiny"]
    assert training_plan(EXTENDED) == [] and renderer_argv(EXTENDED, "--renderer") == []


def test_the_extended_recipes_rear_network_trains_its_own_iterations_and_the_forward_ones_theirs():
    from pathlib import Path

    from drivestudio.commands.recipe_extended import train_argv
    size = Extended(iterations=600, rear_iterations=120)
    forward = [str(a) for a in train_argv(size, Path("d"), Path("f.pt"), 0, rear=False)]
    rear = [str(a) for a in train_argv(size, Path("d"), Path("r.pt"), 0, rear=True)]
    assert forward[forward.index("--iterations") + 1] == "600" and "val_every=100" in forward
    assert rear[rear.index("--iterations") + 1] == "120" and "val_every=20" in rear
    assert "--targets" in rear and "--targets" not in forward
