"""Aggregation rounds drive what the model learned from (drivestudio/worlds/highway/aggregation.py `expert_plan`):
the expert dataset's lane counts, its named tracks and its named conditions, so that a driver trained on a protocol's
training split never meets the protocol's new split in its rounds, and the rounds' frames merge with the expert's."""
import json

import pytest

from drivestudio.worlds.highway.aggregation import AggregationConfig, drive_options, expert_plan, expert_renderer
from perception.shards import MANIFEST


@pytest.fixture
def expert(tmp_path):
    """A dataset whose plan named its lane counts, tracks and conditions: the shared test dataset's frames with its
    manifest's plan as `generate --lanes 2 --tracks oval,procedural:651002 --condition night,rain` records it."""
    from tests.perception.frames import dataset
    manifest = json.loads((dataset() / MANIFEST).read_text())
    manifest["config"]["options"].update(lanes=[2], tracks=["oval", "procedural:651002"], condition="night,rain")
    out = tmp_path / "expert"
    out.mkdir()
    (out / MANIFEST).write_text(json.dumps(manifest))
    return out


def test_the_rounds_take_the_expert_datasets_tracks_conditions_and_lanes(expert, highway_model, tmp_path):
    plan = expert_plan(str(expert))
    assert plan == {"lanes": [2], "tracks": ["oval", "procedural:651002"], "condition": "night,rain"}
    cfg = AggregationConfig(data=str(expert), model="unused.pt", out=str(tmp_path))
    options = drive_options(cfg, 1, highway_model)
    assert options["tracks"] == ["oval", "procedural:651002"] and options["condition"] == "night,rain"
    assert options["lanes"] == [2]


def test_a_dataset_of_generates_default_plan_gives_new_procedural_tracks_each_round_and_no_condition(
        highway_model, tmp_path):
    from tests.perception.frames import dataset
    plan = expert_plan(str(dataset()))
    assert plan["tracks"] == [] and "condition" not in plan
    cfg = AggregationConfig(data=str(dataset()), model="unused.pt", out=str(tmp_path))
    one, two = (drive_options(cfg, r, highway_model)["tracks"] for r in (1, 2))
    assert {t for t in one if t.startswith("procedural:")} != {t for t in two if t.startswith("procedural:")}
    assert "condition" not in drive_options(cfg, 1, highway_model)


@pytest.mark.parametrize("named, drawn", [
    ({"renderer": "tiny"}, "tiny"),
    ({"renderer": "numba"}, "numba"),
    ({"renderer": None, "renderers": ["numba", "tiny"]}, "numba"),   # merged: the default when it is among them
    ({"renderer": None, "renderers": ["egl", "tiny"]}, "egl"),
    ({"renderer": None}, "numba"),                                   # a dataset that does not say: the default
])
def test_the_rounds_draw_with_the_expert_datasets_renderer(expert, named, drawn):
    manifest = json.loads((expert / MANIFEST).read_text())
    manifest.update(named)
    (expert / MANIFEST).write_text(json.dumps(manifest))
    assert expert_renderer(str(expert)) == drawn
