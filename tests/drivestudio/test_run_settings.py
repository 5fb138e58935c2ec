"""The long runs' settings on the command line (drivestudio/commands/run_settings.py): study, aggregate, autonomy
and recipe show as flags only the settings most runs give and take every other one as `--set NAME=VALUE`; a setting
given reaches the run; an unknown or out-of-range one is one line and exit status 2 before any work; the config.json a
run writes runs it again with `--config`; the help's defaults are the configuration's own; and each verb's --help
stays within its count of options."""
from __future__ import annotations

import json

import pytest

from bench.count_options import counts
from core.settings import entries
from drivestudio.cli import main
from drivestudio.commands import aggregate, autonomy, recipe, study
from drivestudio.commands.recipe_steps import RecipeRun
from drivestudio.worlds.highway.aggregation_config import AggregationConfig
from drivestudio.worlds.sidewalk.autonomy import Autonomy
from drivestudio.worlds.sidewalk.study import StudyConfig

LIMITS = {"study": 12, "aggregate": 12, "autonomy": 10, "recipe": 10}   # options each verb's --help shows, at most
CONFIGS = {"study": (StudyConfig, study.FLAGS), "aggregate": (AggregationConfig, aggregate.FLAGS),
           "autonomy": (Autonomy, autonomy.FLAGS), "recipe": (recipe.Size, recipe.FLAGS)}


class Started(Exception):
    """The run got as far as its first step: what that step was asked to do is recorded."""


# where each verb's first step is: the study's and the recipe's first verb (its argv), the aggregation's first round
# and the autonomy run's first drive (their configurations)
FIRST_STEPS = {"study": ("drivestudio.worlds.sidewalk.study", "run_verb"),
               "recipe": ("drivestudio.commands.recipe_steps", "run_verb"),
               "aggregate": ("drivestudio.worlds.highway.aggregation", "Aggregation.do_round"),
               "autonomy": ("drivestudio.worlds.sidewalk.autonomy", "drive_round")}


@pytest.fixture
def first_step(monkeypatch):
    """`first_step(verb)`: that verb's first step recorded (in the dict returned) and then stopped."""
    import importlib
    seen: dict = {}

    def patch(verb: str) -> dict:
        module, name = FIRST_STEPS[verb]
        owner, _, attribute = name.rpartition(".")
        target = importlib.import_module(module)
        if owner:
            target = getattr(target, owner)

        def stop(*args, **kw):
            seen[verb] = args
            raise Started
        monkeypatch.setattr(target, attribute, stop)
        return seen
    return patch


def _started(*argv) -> None:
    with pytest.raises(Started):
        main([str(a) for a in argv])


@pytest.fixture(scope="module")
def sidewalk_model(tmp_path_factory):
    from core.worlds.sidewalk import SIDEWALK
    from perception.checkpoint import save_checkpoint
    from perception.models import Regressor, make_spec
    path = tmp_path_factory.mktemp("models") / "multinet.pt"
    model = Regressor(make_spec("z2color", SIDEWALK, modal=True))
    save_checkpoint(path, {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    return path


# --- a setting given reaches the run -------------------------------------------------------------------------------
def test_a_studys_setting_reaches_its_first_verb(first_step, tmp_path):
    seen = first_step("study")
    _started("study", "--quick", "--out", tmp_path / "s", "--set", "perturbed=0.25", "--set", "episode_frames=30",
             "--seed", 7)
    (argv,) = seen["study"]
    argv = [str(a) for a in argv]
    assert argv[0] == "generate" and argv[argv.index("--perturbed") + 1] == "0.25"
    assert argv[argv.index("--episode-frames") + 1] == "30" and argv[argv.index("--seed") + 1] == "7"


def test_a_studys_conditions_reach_its_data(first_step, tmp_path):
    seen = first_step("study")
    _started("study", "--quick", "--out", tmp_path / "s", "--set", "condition=clear,night", "--set",
             "new_conditions=fog")
    argv = [str(a) for a in seen["study"][0]]
    assert argv[0] == "generate" and argv[argv.index("--set") + 1] == "condition=clear,night"


def test_a_recipes_setting_reaches_its_first_verb(first_step, tmp_path):
    seen = first_step("recipe")
    _started("recipe", "--quick", "--out", tmp_path / "r", "--set", "frames=500", "--workers", 3)
    (argv,) = seen["recipe"]
    argv = [str(a) for a in argv]
    assert argv[:2] == ["generate", "--out"] and argv[argv.index("--frames") + 1] == "500"
    assert argv[argv.index("--workers") + 1] == "3"


def test_an_extended_recipes_setting_reaches_its_first_verb(first_step, tmp_path):
    seen = first_step("recipe")
    _started("recipe", "--extended", "--quick", "--out", tmp_path / "r", "--set", "side_views=false")
    (argv,) = seen["recipe"]
    assert [str(a) for a in argv[argv.index("--set"):argv.index("--set") + 2]] == ["--set", "mirror=true"]


def test_a_recipes_protocol_sets_its_datasets_conditions_and_tracks(first_step, tmp_path):
    """--set protocol=generalisation: the expert's frames are the protocol's training conditions on its training
    tracks, and nothing of its new split."""
    from drivestudio.worlds.highway.benchmark.protocol import load_protocol
    protocol = load_protocol("generalisation")
    seen = first_step("recipe")
    _started("recipe", "--extended", "--quick", "--out", tmp_path / "r", "--set", "protocol=generalisation")
    (argv,) = seen["recipe"]
    argv = [str(a) for a in argv]
    assert argv[argv.index("--condition") + 1].split(",") == list(protocol.conditions["training"])
    assert argv[argv.index("--tracks") + 1].split(",") == list(protocol.tracks["training"])
    assert not set(argv) & {*protocol.conditions["new"], *protocol.tracks["new"]}


def test_a_recipes_unknown_protocol_is_refused_naming_the_setting(run_cli, tmp_path):
    r = run_cli("recipe", "--out", tmp_path / "r", "--set", "protocol=nocrash")
    assert r.returncode == 2 and "--set protocol='nocrash': no such protocol" in r.stderr, r.stderr
    assert not (tmp_path / "r").exists()


def test_a_recipes_condition_mix_reaches_its_dataset_and_the_seeded_look_adds_nothing(first_step, tmp_path):
    seen = first_step("recipe")
    _started("recipe", "--quick", "--out", tmp_path / "r", "--set", "condition=fog,night", "--set", "tracks=oval")
    mixed = [str(a) for a in seen["recipe"][0]]
    _started("recipe", "--quick", "--out", tmp_path / "s")
    seeded = [str(a) for a in seen["recipe"][0]]
    assert mixed[mixed.index("--condition") + 1] == "fog,night" and mixed[mixed.index("--tracks") + 1] == "oval"
    assert "--condition" not in seeded and "--tracks" not in seeded


def test_an_aggregations_setting_reaches_its_first_round(first_step, highway_model, tmp_path):
    seen = first_step("aggregate")
    from tests.perception.frames import dataset
    _started("aggregate", "--data", dataset(), "--model", highway_model, "--out", tmp_path / "a", "--set",
             "frames=60", "--set", "beta=0.3", "--set", "cars=2-5", "--suite", "none")
    run, r = seen["aggregate"]
    assert r == 1 and (run.cfg.frames, run.cfg.beta, run.cfg.car_range, run.cfg.suite) == (60, 0.3, (2, 5), "none")


def test_an_autonomy_setting_reaches_its_drive(first_step, sidewalk_model, tmp_path):
    seen = first_step("autonomy")
    _started("autonomy", "--model", sidewalk_model, "--out", tmp_path / "a", "--mode", "furtive", "--set",
             "obstacles=3", "--set", "video=false")
    drive, out, k = seen["autonomy"][:3]
    assert (drive.mode, drive.obstacles, drive.video, k) == ("furtive", 3.0, False, 0)


# --- bad settings: one line, exit status 2, before any work ---------------------------------------------------------
BAD = [
    ("study", "--set", "moments=5"),                    # below its range
    ("study", "--set", "epochs=many"),
    ("study", "--set", "nope=1"),                       # no such setting
    ("study", "--set", "epochs"),                       # not NAME=VALUE
    ("study", "--quick", "--seed", "-1"),
    ("recipe", "--set", "members=9"),
    ("recipe", "--set", "beta=0.5"),                    # the extended recipe's, without --extended
    ("recipe", "--extended", "--set", "rear_members=5"),
    ("recipe", "--set", "frames=none"),
    ("aggregate", "--data", "d", "--model", "m.pt", "--set", "decay=2"),
    ("aggregate", "--data", "d", "--model", "m.pt", "--set", "cars=300-400"),
    ("aggregate", "--data", "d", "--model", "m.pt", "--set", "lr=0"),
    ("aggregate", "--data", "d", "--model", "m.pt", "--set", "iterations=2.5"),
    ("aggregate", "--model", "m.pt"),                   # no data, here or by --config
    ("autonomy", "--model", "m.pt", "--set", "epochs=0"),
    ("autonomy", "--model", "m.pt", "--set", "wheels=4"),
    ("autonomy", "--model", "m.pt", "--seconds", "0"),
    ("autonomy", "--model", "m.pt", "--set", "device=gpu"),
]


@pytest.mark.parametrize("argv", BAD, ids=lambda a: " ".join(a))
def test_a_bad_setting_is_one_line_and_status_2_before_any_work(run_cli, tmp_path, argv):
    r = run_cli(*argv, "--out", tmp_path / "out", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.startswith(f"drivestudio {argv[0]}: error: ")
    assert sorted(p.name for p in tmp_path.iterdir()) == []          # no output folder, no runs/


@pytest.mark.parametrize("verb", ["study", "recipe", "aggregate"])
@pytest.mark.parametrize("content, says", [
    ({"epochs": 3, "carz": 2}, "unknown field"),
    ([1, 2], "a run configuration is a JSON object"),
])
def test_a_bad_config_file_is_one_line_and_status_2(run_cli, tmp_path, verb, content, says):
    (tmp_path / "c.json").write_text(json.dumps(content))
    r = run_cli(verb, "--config", tmp_path / "c.json", "--out", tmp_path / "out", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and says in r.stderr, r.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("content, says", [
    ({"out": 5}, "out must be a text, got 5"),
    ({"loops": ["procedural:907"]}, "loops must be a text"),
    ({"rounds": 0}, "rounds must be an integer from 1 to 20"),
])
def test_a_studys_config_file_is_held_to_its_settings(run_cli, tmp_path, content, says):
    (tmp_path / "c.json").write_text(json.dumps(content))
    r = run_cli("study", "--config", tmp_path / "c.json", "--out", tmp_path / "out", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and says in r.stderr, r.stderr


def test_quick_and_config_are_one_or_the_other(run_cli, tmp_path):
    (tmp_path / "c.json").write_text("{}")
    for verb in ("study", "recipe"):
        r = run_cli(verb, "--quick", "--config", tmp_path / "c.json", cwd=tmp_path)
        assert r.returncode == 2 and "give one of the two" in r.stderr, r.stderr


# --- config.json runs it again --------------------------------------------------------------------------------------
def test_a_studys_config_runs_it_again_and_options_beside_it_override_it(first_step, tmp_path):
    seen = first_step("study")
    _started("study", "--quick", "--out", tmp_path / "a", "--set", "rounds=1", "--set", "loops=procedural:913",
             "--seed", 3)
    saved = json.loads((tmp_path / "a" / "config.json").read_text())
    assert (saved["rounds"], saved["loops"], saved["seed"], saved["moments"]) == (1, "procedural:913", 3, 240)
    first = seen.pop("study")
    _started("study", "--config", tmp_path / "a" / "config.json", "--out", tmp_path / "b")
    again = json.loads((tmp_path / "b" / "config.json").read_text())
    assert again == {**saved, "out": str(tmp_path / "b")}
    assert [str(a) for a in seen["study"][0]] == [str(a).replace(f"{tmp_path}/a/", f"{tmp_path}/b/")
                                                        for a in first[0]]
    _started("study", "--config", tmp_path / "a" / "config.json", "--out", tmp_path / "c", "--set", "epochs=5")
    assert json.loads((tmp_path / "c" / "config.json").read_text()) == {**saved, "out": str(tmp_path / "c"),
                                                                        "epochs": 5}


def test_a_recipes_config_runs_it_again(first_step, tmp_path):
    first_step("recipe")
    _started("recipe", "--extended", "--quick", "--out", tmp_path / "a", "--set", "rear_members=2", "--workers", 1)
    saved = json.loads((tmp_path / "a" / "config.json").read_text())
    assert saved["recipe"] == "extended" and saved["settings"]["rear_members"] == 2
    assert saved["settings"]["frames"] == recipe.EXTENDED_QUICK.frames
    _started("recipe", "--config", tmp_path / "a" / "config.json")    # the same folder: it continues there
    assert json.loads((tmp_path / "a" / "config.json").read_text()) == saved
    r = main(["recipe", "--config", str(tmp_path / "a" / "config.json"), "--set", "side_views=maybe"])
    assert r == 2


def test_an_aggregations_config_runs_it_again(first_step, highway_model, tmp_path):
    seen = first_step("aggregate")
    from tests.perception.frames import dataset
    _started("aggregate", "--data", dataset(), "--model", highway_model, "--out", tmp_path / "a", "--set",
             "frames=60", "--set", "lr=0.001", "--suite", "none", "--workers", 1)
    saved = json.loads((tmp_path / "a" / "config.json").read_text())
    first = seen.pop("aggregate")[0].cfg
    _started("aggregate", "--config", tmp_path / "a" / "config.json")
    assert seen["aggregate"][0].cfg == first and first.lr == 0.001 and first.workers == 1
    assert json.loads((tmp_path / "a" / "config.json").read_text()) == saved


# --- --help: the configuration's own defaults, and few options --------------------------------------------------------
@pytest.mark.parametrize("verb", LIMITS)
def test_the_help_shows_the_configurations_own_defaults(run_cli, verb):
    config_type, flags = CONFIGS[verb]
    text = " ".join(run_cli(verb, "--help").stdout.split()).split(" options: ", 1)[1]
    for path, e in entries(config_type).items():
        if path in flags:
            if e.default is not None:
                assert f"(default {e.default})" in text.split(e.flag + " ", 1)[1].split(" --")[0], path
        else:
            shown = str(e.default).lower() if isinstance(e.default, bool) else "none" if e.default is None else \
                str(e.default)
            assert f" {path}={shown}" in text, path


def test_the_recipes_flags_are_its_runs_settings():
    assert set(recipe.FLAGS) == set(entries(RecipeRun))


@pytest.mark.parametrize("world", ["highway", "sidewalk"])
def test_each_long_runs_help_shows_few_options(world):
    shown = counts(world)
    assert {verb: shown[verb] for verb in LIMITS} == {verb: min(shown[verb], n) for verb, n in LIMITS.items()}
