"""Bad options given to gymnasium.make: one EnvOptionError naming the option, and nothing left running (the
process table is read); an environment left unclosed ends cleanly at interpreter exit."""
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest

import sim  # noqa: F401  registers the environments
from sim.gym_options import EnvOptionError
from sim.highway.sumo_connection import libsumo_free
from sim.highway.world import World, WorldConfig
from tests.sim.sumo_processes import sumo_children

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DRIVESTUDIO_CACHE", str(tmp_path / "cache"))


@pytest.mark.parametrize("kwargs, option", [
    ({"observation": "pixels"}, "option observation: must be one of camera, affordances, both, got 'pixels'"),
    ({"cars": 301}, "option cars: must be an integer from 0 to 300"),
    ({"track": "ring", "lanes": 1, "cars": 100}, "option cars: 100 cars do not fit on track 'ring'"),
    ({"lanes": 9}, "option lanes: must be an integer from 1 to 4"),
    ({"width": 8}, "option width: must be an integer from 16 to 4096"),
    ({"start_speed": float("nan")}, "option start_speed"),
    ({"max_steps": 0}, "option max_steps"),
    ({"renderer": "vulkan"}, "option renderer"),
    ({"track": "nowhere"}, "option track: unknown track preset"),
])
def test_highway_bad_option(kwargs, option):
    with World(WorldConfig(cars=4, render=False)):   # another world holds libsumo: the new one would use TraCI
        with pytest.raises(EnvOptionError, match="^drivestudio/Highway-v0: " + option.replace("(", r"\(")):
            gym.make("drivestudio/Highway-v0", **kwargs)
        assert sumo_children() == []
    assert libsumo_free()


@pytest.mark.parametrize("kwargs, option", [
    ({"observation": "lidar"}, "option observation"),
    ({"mode": "sprint"}, "option mode: must be one of direct, follow, furtive"),
    ({"obstacles": 99.0}, "option obstacles: the obstacle density must be from 0 to 12"),
    ({"path": "nowhere"}, "option path"),
    ({"height": 5000}, "option height"),
])
def test_sidewalk_bad_option(kwargs, option):
    with pytest.raises(EnvOptionError, match="^drivestudio/Sidewalk-v0: " + option):
        gym.make("drivestudio/Sidewalk-v0", **kwargs)


EXIT_SCRIPT = """
import sys, gymnasium as gym, sim
from stable_baselines3.common.env_checker import check_env
a = gym.make("drivestudio/Highway-v0", track="oval", lanes=3, cars=4)
check_env(a, warn=False)      # leaves references in cycles: freed only after modules are torn down
b = gym.make("drivestudio/Highway-v0", track="oval", lanes=3, cars=4)
b.reset(seed=1)
b.step(b.action_space.sample())
print(b.unwrapped._world._traffic._conn.pid)   # the TraCI world's sumo
"""


def test_unclosed_worlds_end_cleanly_at_exit():
    pytest.importorskip("stable_baselines3")
    proc = subprocess.run([sys.executable, "-c", EXIT_SCRIPT], cwd=REPO, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "Exception ignored" not in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    assert not Path(f"/proc/{int(proc.stdout.split()[-1])}").exists()   # its sumo process ended with it
