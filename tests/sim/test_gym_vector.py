"""gym.make_vec, sync (every world in this process: one libsumo, the others over TraCI) and async (a process per
world), for both worlds: reset(seed=S) gives index i the seed S + i, so the worlds differ from one another and the
same S gives the same worlds again."""
import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401  registers the environments
from tests.sim.sumo_processes import sumo_children

WORLDS = {"highway": ("drivestudio/Highway-v0", {"track": "oval", "lanes": 3, "cars": 8}),
          "sidewalk": ("drivestudio/Sidewalk-v0", {"mode": "follow"})}
STEPS = 15


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DRIVESTUDIO_CACHE", str(tmp_path / "cache"))


def rollout(world: str, mode: str, seed: int) -> np.ndarray:
    """Affordances of the 2 worlds after reset(seed) and STEPS steps of a fixed action: (STEPS + 1, 2, n)."""
    name, kwargs = WORLDS[world]
    envs = gym.make_vec(name, num_envs=2, vectorization_mode=mode, observation="affordances", **kwargs)
    try:
        obs, _ = envs.reset(seed=seed)
        seen = [obs]
        action = np.tile((envs.single_action_space.low + envs.single_action_space.high) / 2 + 0.1, (2, 1))
        for _ in range(STEPS):
            obs, *_ = envs.step(action.astype(np.float32))
            seen.append(obs)
        return np.stack(seen)
    finally:
        envs.close()


@pytest.mark.parametrize("mode", ["sync", "async"])
@pytest.mark.parametrize("world", ["highway", "sidewalk"])
def test_vector_env_seeds_distinct_reproducible_worlds(world, mode):
    a = rollout(world, mode, 11)
    assert not np.array_equal(a[:, 0], a[:, 1])             # index 0 (seed 11) and index 1 (seed 12) differ
    np.testing.assert_array_equal(a, rollout(world, mode, 11))   # and come back the same
    assert sumo_children() == []


def test_sync_and_async_agree():
    # the same seeds give the same worlds whether they share this process (libsumo + TraCI) or have one each
    np.testing.assert_array_equal(rollout("highway", "sync", 3), rollout("highway", "async", 3))
