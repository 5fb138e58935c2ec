"""The Gymnasium environment takes scenario= (docs/scenarios.md): every reset replays it, the episode ends with it, and
info carries its events and verdict."""
import json

import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401 - registers the environments
from sim.gym_options import EnvOptionError

BRAKE = {"version": 2, "name": "brake", "route": {"track": "oval", "lanes": 2, "seed": 4, "seconds": 3},
         "host": {"s": 0, "lane": 1, "speed": 15}, "actors": [{"name": "lead", "gap": 30, "speed": 15}],
         "events": [{"actor": "lead", "when": {"time": 1}, "do": "brake", "decel": 5, "speed": 5}]}


@pytest.fixture
def path(tmp_path):
    p = tmp_path / "brake.json"
    p.write_text(json.dumps(BRAKE))
    return p


def episode(env, seed):
    obs, info = env.reset(seed=seed)
    trace = [obs]
    while True:
        obs, _, terminated, truncated, info = env.step(np.array([0.0, 0.2, 0.0], dtype=np.float32))
        trace.append(obs)
        if terminated or truncated:
            return np.array(trace), truncated, info


def test_the_environment_replays_its_scenario_on_every_reset_and_ends_with_it(path):
    env = gym.make("drivestudio/Highway-v0", scenario=str(path), observation="affordances")
    try:
        first, truncated, info = episode(env, 1)
        again, _, _ = episode(env, 2)            # another seed: the scenario keeps its own
    finally:
        env.close()
    assert truncated and len(first) == 31    # 3 s at 10 Hz, and the first observation
    assert np.array_equal(first, again)
    assert info["scenario"]["events"][0]["do"] == "brake" and info["lanes"] == 2


def test_a_static_scenario_or_a_bad_one_is_refused_by_the_environment(tmp_path):
    static = tmp_path / "static.json"
    static.write_text(json.dumps({"track": "oval", "ego": {"s": 0, "d": 0}}))
    with pytest.raises(EnvOptionError, match="option scenario: .*static scenario"):
        gym.make("drivestudio/Highway-v0", scenario=str(static))
    with pytest.raises(EnvOptionError, match="option scenario: must be the path"):
        gym.make("drivestudio/Highway-v0", scenario=3)
