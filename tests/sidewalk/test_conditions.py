"""The sidewalk's named conditions (docs/conditions.md): the default keeps today's stereo pairs, the times of day are
the highway's names (clear: noon, overcast, low_sun: evening), fog fades with distance and night is dark in both
images, and the truth never changes with the condition."""
from __future__ import annotations

import numpy as np
import pytest

from core.conditions import CONDITIONS, SEEDED
from drivestudio import worlds
from sim.sidewalk.conditions import TIME, draw_condition
from sim.sidewalk.config import SidewalkConfig, StereoConfig
from sim.sidewalk.look import make_look
from sim.sidewalk.stereo import StereoRenderer
from sim.sidewalk.world import SidewalkWorld

RIG = StereoConfig(width=168, height=94)


def pair(name: str, seed: int = 0, steps: int = 8):
    """The stereo pair after `steps` steps straight ahead on the park preset, the truth record and the world."""
    with SidewalkWorld(SidewalkConfig(path="park", seed=seed, condition=name, stereo=RIG, obstacles=0.0)) as world:
        for _ in range(steps):
            obs = world.step([0.5, 0.62])
        return obs.frames, obs.record, world


def test_the_default_is_the_seeded_look_and_keeps_the_pairs_of_before():
    (left, right), record, world = pair(SEEDED)
    assert SidewalkConfig().condition == SEEDED and world.condition == SEEDED
    assert world.declaration.columns[-1].name == "path"   # no condition column
    before = StereoRenderer(world.layout, world.seed, RIG)
    x, y, yaw = (float(record[world.declaration.index(n)]) for n in ("x", "y", "yaw"))
    assert all(np.array_equal(a, b) for a, b in zip((left, right), before.render(x, y, yaw)))


def test_the_times_of_day_are_named_conditions():
    times = {seed: make_look(seed, "park").time for seed in range(30)}
    for name, time in TIME.items():
        seed = next(s for s, t in times.items() if t == time)
        assert np.array_equal(pair(name, seed, 1)[0][0], pair(SEEDED, seed, 1)[0][0]), name


@pytest.mark.parametrize("name", CONDITIONS[1:])
def test_every_condition_draws_both_images_and_leaves_the_truth(name):
    (left, right), record, world = pair(name)
    (cl, cr), clear_record, _ = pair("clear")
    assert left.shape == right.shape == (94, 168, 3) and world.condition == name
    assert world.declaration.columns[-1].name == "condition"
    assert np.array_equal(record, clear_record)
    if name != "clear":
        assert np.abs(left.astype(int) - cl).mean() > 3 and np.abs(right.astype(int) - cr).mean() > 3


def test_fog_fades_the_far_more_than_the_near_and_night_is_dark():
    """Against the overcast look (the fog's own, but its sky), the path far ahead keeps little of its contrast with
    the fog and the path at the car's nose nearly all of it."""
    (fog, _), _, world = pair("fog")
    (overcast, _), _, _ = pair("overcast")
    (clear, _), _, _ = pair("clear")
    grey = np.array(draw_condition("fog", 0, "park").fog_rgb) * 255.0
    horizon = int(round(world.renderer.cameras["left"].horizon_row()))
    path = slice(74, 94)   # the path ahead: no hedge there
    kept = [np.abs(fog[rows, path].astype(float) - grey).mean() /
            np.abs(overcast[rows, path].astype(float) - grey).mean()
            for rows in (slice(horizon + 1, horizon + 3), slice(84, 94))]
    assert kept[0] < 0.3 and kept[1] > 0.9
    (night, _), _, _ = pair("night")
    assert night.mean() < 0.35 * clear.mean()
    bottom = night[70:].astype(float).mean(axis=(0, 2))
    assert bottom[74:94].mean() > 2 * max(bottom[:15].mean(), bottom[-15:].mean())   # the car's lamps, ahead


def test_render_names_the_condition_and_the_time_of_day():
    plugin = worlds.get("sidewalk")
    frames, truth = plugin.render(SidewalkConfig(path="park", seed=1, condition="fog,night", stereo=RIG))
    assert truth["condition"] in ("fog", "night") and truth["time_of_day"] == truth["condition"]
    assert frames["left"].shape == (94, 168, 3)
