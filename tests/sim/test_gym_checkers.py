"""Gymnasium's and Stable-Baselines3's environment checkers on both worlds, every observation kind.

The warnings kept (docs/gymnasium.md): Stable-Baselines3 recommends an action space symmetric in [-1, 1] (both
worlds keep their declared command, as every driver and the bridge send it; gymnasium.wrappers.RescaleAction
removes the warning, checked below) and calls the sidewalk's stereo pair (2, height, width, 3) an unconventional
shape (observation="both" gives the two images apart). Nothing else may warn.
"""
import gc
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import sim  # noqa: F401  registers the environments
from tests.sim.sumo_processes import sumo_children

sb3 = pytest.importorskip("stable_baselines3.common.env_checker")   # the optional `rl` extra

SYMMETRIC = "symmetric and normalized Box action space"
STEREO = "unconventional shape"
WORLDS = {"highway": ("drivestudio/Highway-v0", {"track": "oval", "lanes": 3, "cars": 12}),
          "sidewalk": ("drivestudio/Sidewalk-v0", {"mode": "direct"})}


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DRIVESTUDIO_CACHE", str(tmp_path / "cache"))


def checked(env) -> list[str]:
    """Both checkers on env; the warnings they raised (not those of what an earlier test in this process left to
    the garbage collector: an unclosed pipe of a process it started)."""
    gc.collect()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)        # makes a second world for its determinism test: two highways at once
        sb3.check_env(env)
    return [str(w.message) for w in caught]


@pytest.mark.parametrize("observation", ["camera", "affordances", "both"])
@pytest.mark.parametrize("world", ["highway", "sidewalk"])
def test_both_checkers_pass_with_only_the_documented_warnings(world, observation):
    name, kwargs = WORLDS[world]
    env = gym.make(name, observation=observation, **kwargs)
    try:
        found = checked(env)
    finally:
        env.close()
    kept = [SYMMETRIC] + ([STEREO] if (world, observation) == ("sidewalk", "camera") else [])
    assert sorted(k for k in kept if any(k in w for w in found)) == sorted(kept)
    assert [w for w in found if not any(k in w for k in kept)] == []
    assert sumo_children() == []


@pytest.mark.parametrize("world", ["highway", "sidewalk"])
def test_rescaled_actions_leave_no_warning(world):
    name, kwargs = WORLDS[world]
    inner = gym.make(name, observation="affordances", **kwargs)
    one = np.ones(inner.action_space.shape, np.float32)   # float32 bounds, as the action space's
    env = gym.wrappers.RescaleAction(inner, -one, one)
    try:
        assert checked(env) == []
    finally:
        env.close()
