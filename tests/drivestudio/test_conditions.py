"""Choosing a named condition (docs/conditions.md): `--condition NAME[,NAME...]` on the verbs that make a highway
world and on benchmark, `--set condition=` and a run's config.json, `condition=` in Gymnasium; an unknown name is
refused in one line, exit status 2, before any work; generate records each frame's condition, and its labels are
those of the same episodes in any other condition."""
from __future__ import annotations

import json

import gymnasium as gym
import pyarrow.parquet as pq
import pytest

import sim  # noqa: F401  registers the environments
from core.conditions import pick
from core.settings import SettingError, check
from perception.shards import Dataset, label_columns
from sim.gym_options import EnvOptionError
from sim.highway.config import WorldConfig

SMALL = ["--frames", "20", "--episode-frames", "10", "--tracks", "oval", "--lanes", "2", "--cars", "0", "--warmup",
         "0", "--workers", "1", "--set", "camera.width=70", "--set", "camera.height=53"]


@pytest.mark.parametrize("argv", [
    ["render", "--condition", "snow", "-o", "{out}/f.png"],
    ["render", "--condition", "fog,snow", "-o", "{out}/f.png"],
    ["render", "--set", "condition=hail", "-o", "{out}/f.png"],
    ["generate", "--condition", "dusk", "--out", "{out}/ds", "--frames", "20"],
    ["drive", "--condition", "drizzle", "--seconds", "1", "--out", "{out}/run"],
    ["benchmark", "--condition", "sleet", "--out", "{out}/bench"],
    ["studio", "--condition", "mist", "--out", "{out}/studio"],
])
def test_an_unknown_condition_is_refused_in_one_line_before_any_work(run_cli, tmp_path, argv):
    r = run_cli(*[a.format(out=tmp_path) for a in argv])
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "invalid choice" in r.stderr and "seeded, clear, overcast, low_sun, night, fog, rain" in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_config_file_with_an_unknown_condition_is_refused(run_cli, tmp_path):
    config = tmp_path / "config.json"
    config.write_text(json.dumps({"world": "highway", "settings": {"condition": "blizzard"}}))
    r = run_cli("drive", "--config", config, "--seconds", "1", "--out", tmp_path / "run")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "condition: invalid choice: 'blizzard'" in r.stderr
    assert not (tmp_path / "run").exists()
    with pytest.raises(SettingError):
        check(WorldConfig(condition="clear,blizzard"))


def test_render_draws_the_condition_chosen(run_cli, tmp_path):
    for name in ("clear", "night"):
        r = run_cli("render", "--condition", name, "--cars", "0", "--set", "camera.width=70", "--set",
                    "camera.height=53", "-o", tmp_path / f"{name}.png")
        assert r.returncode == 0, r.stderr
    import cv2
    clear, night = (cv2.imread(str(tmp_path / f"{n}.png")) for n in ("clear", "night"))
    assert night.mean() < 0.5 * clear.mean()


def test_generate_records_each_frames_condition_and_the_same_labels(run_cli, tmp_path):
    """A dataset of named conditions has the condition column (metadata, as `track`: not a label); a dataset of the
    seeded look has none, as before; the labels of the same episodes are the same."""
    for out, extra in (("seeded", []), ("mixed", ["--condition", "night,fog,rain"])):
        r = run_cli("generate", "--out", tmp_path / out, *SMALL, *extra)
        assert r.returncode == 0, r.stderr[-2000:]
    seeded, mixed = Dataset(tmp_path / "seeded"), Dataset(tmp_path / "mixed")
    assert "condition" not in [c.name for c in seeded.declaration.columns]
    assert mixed.declaration.columns[-1].name == "condition" and "condition" not in mixed.declaration.targets
    for a, b in zip(seeded.shards, mixed.shards):
        ta, tb = pq.read_table(tmp_path / "seeded" / a.file), pq.read_table(tmp_path / "mixed" / b.file)
        assert set(tb.column("condition").to_pylist()) == {pick("night,fog,rain", tb.column("seed")[0].as_py())}
        for name in label_columns(seeded.declaration):
            assert ta.column(name).to_pylist() == tb.column(name).to_pylist(), name
        assert ta.column("image_front").to_pylist() != tb.column("image_front").to_pylist()
    assert json.loads((tmp_path / "mixed" / "manifest.json").read_text())["config"]["options"]["condition"] == \
        "night,fog,rain"


def test_gymnasium_takes_the_condition():
    env = gym.make("drivestudio/Highway-v0", track="oval", lanes=2, cars=0, width=70, height=53,
                   condition="clear,night")
    try:
        seen = {}
        for seed in range(8):
            obs, info = env.reset(seed=seed)
            assert info["condition"] == pick("clear,night", seed)
            seen.setdefault(info["condition"], []).append(obs.mean())
        assert set(seen) == {"clear", "night"} and max(seen["night"]) < 0.5 * min(seen["clear"])
    finally:
        env.close()
    with pytest.raises(EnvOptionError, match="option condition: invalid choice: 'fogg'"):
        gym.make("drivestudio/Highway-v0", condition="fogg")
    plain = gym.make("drivestudio/Highway-v0", track="oval", lanes=2, cars=0, width=70, height=53)
    try:
        assert "condition" not in plain.reset(seed=0)[1]
    finally:
        plain.close()


def test_benchmark_routes_get_the_condition():
    from drivestudio.worlds.highway.benchmark.route import RunOptions, world_for
    from drivestudio.worlds.highway.benchmark.suite import Route
    route = Route("r", "oval", 2, 0, 11, None, 10.0)   # no cars: no SUMO to start
    with world_for(route, condition="fog,rain") as world:
        assert world.config.condition == "fog,rain" and world.condition == pick("fog,rain", route.seed)
        assert world.observe().frame.mean() > 0
    assert RunOptions().condition == "seeded"


def test_the_studio_records_the_condition_it_draws(tmp_path):
    from dataclasses import replace

    from drivestudio import worlds
    from drivestudio.studio.controls import Controls
    from drivestudio.studio.protocol import Message
    from drivestudio.studio.publisher import Publisher
    from drivestudio.studio.session import Session
    from drivestudio.studio.watch import Watch
    plugin = worlds.get("highway")
    config = replace(plugin.config_type(), cars=0, condition="fog", camera=replace(plugin.config_type().camera,
                                                                                  width=70, height=53))
    s = Session(plugin, config, tmp_path, {}, Watch(Publisher(), None), Controls(realtime=False), shard_steps=40,
                model="oracle")
    s.open()
    s.handle(Message("record", {"on": True, "name": "fog"}))
    s.run(seconds=1.0)
    s.handle(Message("record", {"on": False}))
    data = Dataset(tmp_path / "recordings" / "fog")
    assert set(data.labels(None, ["condition"])["condition"].tolist()) == {"fog"}
