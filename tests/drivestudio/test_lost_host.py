"""A host car that leaves the road for good: `generate` puts it back and records on (when_lost="recover"), a
benchmark route ends with "host lost"; both worlds answer the loop's `recover` (drivestudio/loop.py's World)."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from core.worlds.highway import HIGHWAY
from drivestudio.generate import GenerateConfig, record_episode
from drivestudio.loop import in_process, run_loop
from drivestudio.worlds import Episode, get
from drivestudio.worlds.highway import Plugin as HighwayPlugin
from drivestudio.worlds.highway.benchmark import ModelSpec, RunOptions
from drivestudio.worlds.highway.benchmark import route as route_module
from drivestudio.worlds.highway.benchmark.suite import Route
from perception.shards import ShardReader
from sim.highway.world import World, WorldConfig

D = HIGHWAY.index("d")


class HardLeft:
    """Full lock left and full throttle: off the left edge of the road within seconds, then lost (6 m beyond)."""

    name = "hard-left"

    def __init__(self):
        self.timings = {"control": 0.0}

    def act(self, percept):
        return np.array([1.0, 1.0, 0.0]), np.full(len(HIGHWAY.estimate_names), np.nan)


class LosingPlugin(HighwayPlugin):
    """The highway's generation plan with the expert replaced by HardLeft."""

    def episode(self, ep, options, renderer):
        world, _, columns = super().episode(ep, options, renderer)
        return world, HardLeft(), columns


def test_the_highway_world_puts_a_lost_host_car_back_on_a_lane_centre():
    with World(WorldConfig(track="oval", lanes=3, cars=0, render=False, start_speed=15.0)) as world:
        last = run_loop(world, in_process(HardLeft()), 60.0, render=False)
        assert last.end == "host lost"
        world.recover()
        obs = world.observe(render=False)
        assert obs.end is None and not obs.off_road
        assert np.isclose(obs.record[D], world.track.lane_centres).any()


def test_generate_records_on_after_the_host_car_is_lost(tmp_path: Path):
    plugin = LosingPlugin()
    options = {"tracks": ["oval"], "procedural": 0, "lanes": [2], "cars": [0, 0], "width": 280, "height": 210,
               "fov": 60.0}
    ep = Episode(0, 150, 7, {"track": "oval", "lanes": 2, "cars": 0})
    entry = record_episode(plugin, ep, GenerateConfig(frames=150, episode_frames=150, warmup=0.0, options=options),
                           str(tmp_path))
    assert entry["frames"] == 150
    d = np.asarray(ShardReader(tmp_path / entry["file"], HIGHWAY).labels(["d"]).column("d").to_pylist())
    assert len(d) == 150
    assert np.isclose(d, 2.0).sum() + np.isclose(d, -2.0).sum() >= 2   # the start and at least one recovery
    assert (np.abs(d) > 4.0).any()                                     # it did leave the road


def test_a_benchmark_route_whose_host_car_is_lost_ends_there(monkeypatch, tmp_path):
    monkeypatch.setattr(route_module, "driver_for", lambda model, device: HardLeft())
    route = Route("lost", "oval", 2, 0, 5, 0, 60.0, "oval", 1.0)
    result = route_module.run_route(route, ModelSpec("oracle", None), RunOptions(clips=0))
    assert result["end"] == "host lost"
    assert 0 < result["driven_s"] < 60.0
    assert route_module.completion(result) < 1.0


@pytest.mark.parametrize("world", ["highway", "sidewalk"])
def test_both_worlds_keep_the_loop_contract(world):
    """Every method and attribute of drivestudio.loop.World, by the same names in both worlds."""
    plugin = get(world)
    with plugin.world(replace(plugin.config_type(), render=False)) as w:
        for name in ("declaration", "dt", "timings", "observe", "step", "recover", "close"):
            assert hasattr(w, name), name
        assert isinstance(w.declaration, type(HIGHWAY))
        assert isinstance(w.dt, float) and w.dt > 0
