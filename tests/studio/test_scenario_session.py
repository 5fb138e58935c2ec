"""The studio drives a scripted scenario (docs/scenarios.md), shows in its controller panel what the scenario did and
how it goes, and records what is driven."""
import json
from dataclasses import replace

from drivestudio import worlds
from drivestudio.studio.controls import Controls
from drivestudio.studio.protocol import Message
from drivestudio.studio.publisher import Publisher
from drivestudio.studio.session import Session
from drivestudio.studio.watch import Watch
from perception.shards import Dataset
from tests.sim.test_gym_scenario import BRAKE


def test_the_studio_drives_a_scenario_shows_its_verdict_and_records_it(tmp_path):
    path = tmp_path / "brake.json"
    path.write_text(json.dumps(BRAKE))
    plugin = worlds.get("highway")
    config = plugin.settle(replace(plugin.config_type(), scenario=str(path)))
    assert (config.track, config.lanes, config.cars, config.seed) == ("oval", 2, 0, 4)
    s = Session(plugin, config, tmp_path, {}, Watch(Publisher(), None), Controls(realtime=False), shard_steps=20,
                model="oracle")
    s.open()
    panel = {}
    step = s.on_step

    def on_step(rec) -> None:
        step(rec)
        panel.update(s.watch.view.controller(s.driver, s.supervisor, rec))
    s.on_step = on_step     # type: ignore[method-assign]
    s.handle(Message("record", {"on": True, "name": "faced"}))
    s.run(seconds=3.0)
    assert panel["scenario"] == "brake: 1 of 1 events" and panel["verdict"] == "passing so far"
    assert len(Dataset(tmp_path / "recordings" / "faced").labels(columns=["speed"])["speed"]) == 30   # per command
