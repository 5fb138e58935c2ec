"""An action of the wrong length, not numbers or not finite, given to either environment's step(), is refused with
one EnvActionError that names the expected action (its length and names) and what was given, and the world is not
stepped; the right action goes on working after it."""
from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401  registers the environments
from sim.gym_options import EnvActionError

HIGHWAY = "drivestudio/Highway-v0: step() takes an action of 3 numbers (steer, accel, brake)"
SIDEWALK = "drivestudio/Sidewalk-v0: step() takes an action of 2 numbers (steer, motor)"


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DRIVESTUDIO_CACHE", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def highway():
    env = gym.make("drivestudio/Highway-v0", track="oval", lanes=2, cars=0, observation="affordances")
    env.reset(seed=0)
    yield env
    env.close()


@pytest.fixture(scope="module")
def sidewalk():
    env = gym.make("drivestudio/Sidewalk-v0", observation="affordances")
    env.reset(seed=0)
    yield env
    env.close()


@pytest.mark.parametrize("action, given", [
    ([0.0, 0.3], "got 2 numbers: [0. , 0.3]"),
    ([0.0, 0.3, 0.0, 1.0], "got 4 numbers"),
    ([], "got 0 numbers"),
    (0.5, "got 1 number: [0.5]"),
    ("left", "got 'left'"),
])
def test_highway_names_the_expected_action_and_what_was_given(highway, action, given):
    t = highway.unwrapped._world.t
    with pytest.raises(EnvActionError) as e:
        highway.step(action)
    assert str(e.value).startswith(HIGHWAY) and given in str(e.value), str(e.value)
    assert "reshape" not in str(e.value) and "\n" not in str(e.value)
    assert highway.unwrapped._world.t == t   # the world was not stepped
    highway.step(np.array([0.0, 0.3, 0.0], dtype=np.float32))


@pytest.mark.parametrize("action, given", [
    ([0.5, 0.7, 0.0], "got 3 numbers: [0.5, 0.7, 0. ]"),
    ([0.5], "got 1 number: [0.5]"),
    (None, "got None"),
])
def test_sidewalk_names_the_expected_action_and_what_was_given(sidewalk, action, given):
    with pytest.raises(EnvActionError) as e:
        sidewalk.step(action)
    assert str(e.value).startswith(SIDEWALK) and given in str(e.value), str(e.value)
    sidewalk.step([0.5, 0.7])


@pytest.mark.parametrize("env, action, given", [
    ("highway", [math.nan, 0.3, 0.0], "steer=nan"),
    ("highway", [0.0, math.inf, 0.0], "accel=inf"),
    ("sidewalk", [0.5, -math.inf], "motor=-inf"),
    ("sidewalk", [math.nan, math.nan], "steer=nan, motor=nan"),
])
def test_non_finite_values_are_refused_by_name(request, env, action, given):
    e = request.getfixturevalue(env)
    with pytest.raises(EnvActionError, match="takes finite numbers") as err:
        e.step(action)
    assert given in str(err.value)
