"""A model that learned frames with the rear-view mirror is driven by a world that renders one, and one that learned
none is never shown it (docs/rendering.md#the-rear-view-mirror): drive turns the mirror on by itself, the
benchmark renders it for that row only, `--mirror` with a model that learned none is refused in one line (exit
2), and training goes on only with data like the model's own."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from core.worlds.highway import HIGHWAY
from drivestudio.errors import UsageError
from drivestudio.worlds.highway.benchmark.models import check_model
from drivestudio.worlds.highway.plugin import Plugin
from perception.checkpoint import CheckpointError, save_checkpoint
from perception.models import Regressor, frame_inset, make_spec
from perception.train_sgd import check_inset
from sim.highway.config import WorldConfig

MIRRORED = HIGHWAY.with_camera("front", 210, 280, "mirror")
SIDES = HIGHWAY.with_camera("front", 210, 280, "mirror+sides")


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("mirror-models")
    torch.manual_seed(0)
    out = {}
    for name, decl in (("plain", HIGHWAY), ("mirror", MIRRORED), ("sides", SIDES)):
        model = Regressor(make_spec("gist", decl))
        out[name] = root / f"{name}.pt"
        save_checkpoint(out[name], {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    return out


def drive_config(mirror=False, side_views=False) -> WorldConfig:
    """The configuration `drive --mirror --side-views` asks for (the side views bring the mirror)."""
    return Plugin().settle(WorldConfig(track="oval", lanes=3, cars=4, mirror=mirror, side_views=side_views))


def test_the_spec_records_the_inset_of_the_frames_it_learned(models):
    assert frame_inset(make_spec("gist", MIRRORED)) == "mirror"
    assert frame_inset(make_spec("gist", HIGHWAY)) == "" and "inset" not in make_spec("gist", HIGHWAY)["input"]


def resolved(model, mirror=False, side_views=False) -> bool:
    return resolved_inset(model, mirror, side_views) != ""


def resolved_inset(model, mirror=False, side_views=False) -> str:
    plugin = Plugin()
    return plugin.fit_driver(drive_config(mirror, side_views), plugin.parse_driver(str(model))).inset


def test_drive_renders_the_mirror_for_a_model_that_learned_it_and_only_then(models):
    assert resolved(models["mirror"]) is True
    assert resolved(models["mirror"], mirror=True) is True
    assert resolved(models["plain"]) is False
    assert resolved("oracle", mirror=True) is True and resolved("oracle") is False   # a user watching: as asked
    with pytest.raises(UsageError, match="learned frames without the rear-view mirror"):
        resolved(models["plain"], mirror=True)


def test_drive_renders_the_side_views_for_a_model_that_learned_them_and_only_then(models):
    assert resolved_inset(models["sides"]) == "mirror+sides"
    assert resolved_inset(models["sides"], mirror=True, side_views=True) == "mirror+sides"
    assert resolved_inset(models["mirror"]) == "mirror"
    assert resolved_inset("oracle", side_views=True) == "mirror+sides"    # side_views brings the mirror with it
    with pytest.raises(UsageError, match="^--set mirror=true: .* learned frames with the rear-view mirror and the "
                                         "side views; drive it with --set side_views=true$"):
        resolved_inset(models["sides"], mirror=True)
    with pytest.raises(UsageError, match="^--set side_views=true: .* learned frames with the rear-view mirror; "
                                         "drive it with --set mirror=true$"):
        resolved_inset(models["mirror"], side_views=True)


def test_a_running_world_unlike_the_models_frames_is_refused(models):
    """Over the bridge or in the studio the world runs before the driver is made: its declaration decides."""
    plugin = Plugin()
    assert plugin.driver(plugin.parse_driver(str(models["mirror"])), "cpu", MIRRORED) is not None
    assert plugin.driver(plugin.parse_driver(str(models["plain"])), "cpu", HIGHWAY) is not None
    with pytest.raises(UsageError, match="learned frames with the rear-view mirror and this world's are without the "
                                         "rear-view mirror: start the world with --set mirror=true$"):
        plugin.driver(plugin.parse_driver(str(models["mirror"])), "cpu", HIGHWAY)
    with pytest.raises(UsageError, match="learned frames without the rear-view mirror and this world's are with the "
                                         "rear-view mirror: start the world without the mirror"):
        plugin.driver(plugin.parse_driver(str(models["plain"])), "cpu", MIRRORED)
    with pytest.raises(UsageError, match="with the rear-view mirror and the side views and this world's are with the "
                                         "rear-view mirror: start the world with --set side_views=true"):
        plugin.driver(plugin.parse_driver(str(models["sides"])), "cpu", MIRRORED)


def test_the_benchmark_renders_the_mirror_for_that_row(models):
    assert check_model(str(models["mirror"])).inset == "mirror"
    assert check_model(str(models["sides"])).inset == "mirror+sides"
    assert check_model(str(models["plain"])).inset == "" and check_model("oracle").inset == ""
    assert "with mirror" in check_model(str(models["mirror"])).label


def test_drive_with_a_mirror_model_runs_with_the_mirror(models, tmp_path, run_cli):
    run = run_cli("drive", "--model", models["mirror"], "--track", "oval", "--lanes", "2", "--cars", "2",
                  "--seconds", "1", "--in-process", "--out", tmp_path)
    assert run.returncode == 0, run.stderr
    assert json.loads((tmp_path / "metrics.json").read_text())["mirror"] is True


def test_mirror_with_a_model_that_learned_none_is_one_line_and_exit_2(models, tmp_path, run_cli):
    run = run_cli("drive", "--model", models["plain"], "--set", "mirror=true", "--seconds", "1",
                  "--out", tmp_path / "run")
    assert run.returncode == 2
    assert run.stderr.strip().count("\n") == 0 and "without the rear-view mirror" in run.stderr
    assert not (tmp_path / "run").exists()


def test_training_goes_on_only_with_frames_like_the_models_own(models):
    mirrored = make_spec("gist", MIRRORED)
    check_inset("m.pt", mirrored, MIRRORED)
    check_inset("p.pt", make_spec("gist", HIGHWAY), HIGHWAY)
    with pytest.raises(CheckpointError, match="learned frames with the mirror inset"):
        check_inset("m.pt", mirrored, HIGHWAY)
    with pytest.raises(CheckpointError, match="with the mirror\\+sides inset; this data's frames are with the mirror "):
        check_inset("s.pt", make_spec("gist", SIDES), MIRRORED)
    with pytest.raises(CheckpointError, match="learned frames without an inset"):
        check_inset("p.pt", make_spec("gist", HIGHWAY), MIRRORED)


@pytest.mark.long
def test_generate_records_the_mirror_and_such_data_does_not_merge_with_data_without(tmp_path, run_cli):
    """...and aggregation rounds drive the lane counts of the expert data they are merged with."""
    from perception.merge import Source, merge
    from perception.shards import Dataset, DatasetError

    for name, extra in (("plain", []), ("mirror", ["--set", "mirror=true", "--lanes", "2,4"]),
                        ("sides", ["--set", "side_views=true"])):
        run = run_cli("generate", "--out", tmp_path / name, "--frames", "24", "--episode-frames", "12",
                      "--workers", "1", "--cars", "4", *extra)
        assert run.returncode == 0, run.stderr
    assert Dataset(tmp_path / "mirror").declaration.cameras[0].inset == "mirror"
    assert Dataset(tmp_path / "plain").declaration.cameras[0].inset == ""
    assert Dataset(tmp_path / "sides").declaration.cameras[0].inset == "mirror+sides"   # side_views: the mirror too
    from drivestudio.worlds.highway.aggregation import expert_plan
    assert expert_plan(str(tmp_path / "mirror"))["lanes"] == [2, 4]
    assert expert_plan(str(tmp_path / "plain"))["lanes"] == [1, 2, 3]
    with pytest.raises(DatasetError, match="another world or camera"):
        merge(tmp_path / "merged", [Source(tmp_path / "plain"), Source(tmp_path / "mirror")], log=lambda *a: None)
    with pytest.raises(DatasetError, match="another world or camera"):
        merge(tmp_path / "merged", [Source(tmp_path / "mirror"), Source(tmp_path / "sides")], log=lambda *a: None)
    assert not (tmp_path / "merged").exists()


@pytest.fixture(scope="module")
def extended_mirror_model(tmp_path_factory) -> Path:
    from core.worlds.highway import LABEL_SETS
    path = tmp_path_factory.mktemp("extended") / "ext-mirror.pt"
    model = Regressor(make_spec("gist", MIRRORED, LABEL_SETS["extended"]))
    save_checkpoint(path, {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    return path


@pytest.mark.parametrize("name", ["plain", "extended"])
def test_aggregation_drives_the_learner_as_the_benchmark_does(models, extended_mirror_model, name, tmp_path):
    """Its frames are recorded with the mirror when it learned one, and a model of the rear labels drives with the
    lookout, as in `drive` and `benchmark`."""
    from drivestudio.worlds.base import Episode
    from drivestudio.worlds.highway.aggregation import AggregationConfig, AggregationPlugin, drive_options

    learner = extended_mirror_model if name == "extended" else models["plain"]
    from tests.perception.frames import dataset
    cfg = AggregationConfig(data=str(dataset()), model=str(learner), out=str(tmp_path))
    options = drive_options(cfg, 1, learner)
    assert bool(options.get("mirror")) is (name == "extended")
    assert options["lanes"] == [1, 2, 3]       # the expert dataset's plan
    plugin = AggregationPlugin()
    episode = Episode(0, 2, 7, {"track": "oval", "lanes": 2, "cars": 2})
    world, driver, _ = plugin.episode(episode, options, "tiny")
    try:
        assert driver.learner.lookout is (name == "extended")
        assert world.config.mirror is (name == "extended")
        assert plugin.declaration_for(options).cameras[0].inset == ("mirror" if name == "extended" else "")
    finally:
        world.close()


def test_the_rear_memory_is_refused_for_a_model_that_reads_nothing_behind(models):
    """rear_memory holds the rear labels: a model of the paper's 13 has none, and is refused in one line."""
    plugin = Plugin()
    with pytest.raises(UsageError, match="rear_memory holds the rear labels .* which .*mirror.pt does not"):
        plugin.driver(plugin.parse_driver(f"{models['mirror']}@rear_memory=10"), "cpu", MIRRORED)
    assert plugin.driver(plugin.parse_driver(str(models["mirror"])), "cpu", MIRRORED).filters == []
