"""A trained policy as a driver of the highway: a saved Stable-Baselines3 model (a .zip, as `model.save` writes
it) that reads the affordance observation of drivestudio/Highway-v0 (the 14 indicators and the speed,
sim/highway/gym_env.py), or any Python callable from that observation to an action, named MODULE:NAME.

    drivestudio benchmark --model runs/ppo-highway.zip
    drivestudio benchmark --model policy:mypackage.drivers:careful
    drivestudio drive --model runs/ppo-highway.zip

The driver builds the observation from the truth record exactly as the environment does (one code path,
sim/gym_options.py's Affordances), so a policy drives the benchmark's routes on what it was trained on. A model
whose action space is not the world's (one trained under gymnasium.wrappers.RescaleAction, say) is mapped back
linearly from its own bounds. A policy estimates no label: its estimate record is NaN throughout.
"""
from __future__ import annotations

import importlib
import json
import re
import time
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from core.worlds.highway import HIGHWAY
from drivestudio.errors import UsageError
from drivestudio.loop import Percept

CALLABLE = "policy:"
CALLABLE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.]*:[A-Za-z_][A-Za-z0-9_]*")
ESTIMATE_LEN = len(HIGHWAY.estimate_names)
LOW = np.array([c.low for c in HIGHWAY.action])
HIGH = np.array([c.high for c in HIGHWAY.action])
# Stable-Baselines3's policy classes by module: which algorithm loads a saved model (its zip's "data" says)
ALGORITHMS = {"stable_baselines3.common.policies": "PPO", "stable_baselines3.ppo.policies": "PPO",
              "stable_baselines3.sac.policies": "SAC", "stable_baselines3.td3.policies": "TD3",
              "stable_baselines3.a2c.policies": "A2C"}


def is_policy(text: str) -> bool:
    """Whether a --model value names a policy (a saved model's .zip, or policy:MODULE:NAME)."""
    return text.startswith(CALLABLE) or text.lower().endswith(".zip")


def _algorithm(path: Path) -> str:
    """The Stable-Baselines3 algorithm that saved `path`, from the policy class its zip records."""
    try:
        with zipfile.ZipFile(path) as z:
            data = json.loads(z.read("data"))
    except (OSError, zipfile.BadZipFile, KeyError, ValueError):
        raise UsageError(f"--model {path}: not a saved Stable-Baselines3 model (a zip with its 'data')") from None
    module = str(data.get("policy_class", {}).get("__module__", ""))
    if module not in ALGORITHMS:
        raise UsageError(f"--model {path}: a policy of {module or 'an unknown class'}; drivestudio loads "
                         f"{', '.join(sorted(set(ALGORITHMS.values())))} models")
    return ALGORITHMS[module]


def load_policy(text: str, device: str = "cpu") -> tuple[Callable[[np.ndarray], np.ndarray], tuple, str]:
    """(observation -> action in the world's ranges, the action's (low, high) as the policy gives it, its name),
    checked now: a missing file, a zip that is no saved model, a model of another observation, an unimportable
    callable: one line (UsageError, exit status 2)."""
    if text.startswith(CALLABLE):
        ref = text[len(CALLABLE):]
        if not CALLABLE_NAME.fullmatch(ref):
            raise UsageError(f"--model {text}: a policy callable is policy:MODULE:NAME")
        module, name = ref.split(":")
        try:
            fn = getattr(importlib.import_module(module), name)
        except (ImportError, AttributeError) as e:
            raise UsageError(f"--model {text}: cannot import it ({e})") from None
        if not callable(fn):
            raise UsageError(f"--model {text}: {name} is not callable")
        return fn, (LOW, HIGH), ref
    path = Path(text)
    if not path.is_file():
        raise UsageError(f"--model {text}: no such file")
    algo = _algorithm(path)
    try:
        import stable_baselines3  # lazy, and optional: the `rl` extra
    except ImportError:
        raise UsageError(f"--model {text}: a Stable-Baselines3 model needs the rl extra "
                         "(pip install 'drivestudio[rl]')") from None
    model = getattr(stable_baselines3, algo).load(path, device=device)
    from sim.highway.gym_env import AFFORDANCES  # lazy: Gymnasium and the traffic, for policies only
    space = model.observation_space
    if getattr(space, "shape", None) != AFFORDANCES.space.shape:
        raise UsageError(f"--model {text}: the policy reads observations of shape {getattr(space, 'shape', '?')}; "
                         f"the highway's affordance observation has {AFFORDANCES.space.shape} "
                         "(gymnasium.make('drivestudio/Highway-v0', observation='affordances'))")

    def act(obs: np.ndarray) -> np.ndarray:
        return model.predict(obs, deterministic=True)[0]
    return act, (model.action_space.low, model.action_space.high), f"{algo} policy ({path.name})"


class PolicyDriver:
    """A policy on the exact affordances: the Driver of drivestudio/loop.py."""

    def __init__(self, text: str, device: str = "cpu"):
        from sim.highway.gym_env import AFFORDANCES  # lazy: Gymnasium and the traffic, for policies only
        self._policy, (low, high), self._name = load_policy(text, device)
        self._affordances = AFFORDANCES
        self._low, self._span = np.asarray(low, np.float64), np.asarray(high, np.float64) - np.asarray(low)
        self.timings = {"policy": 0.0}
        self._estimate = np.full(ESTIMATE_LEN, np.nan)

    @property
    def name(self) -> str:
        return self._name

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        out = np.asarray(self._policy(self._affordances(percept.record)), dtype=np.float64).reshape(-1)
        if out.shape != LOW.shape:
            raise ValueError(f"policy {self._name} answered {out.size} values; the highway's action has "
                             f"{LOW.size} ({', '.join(HIGHWAY.action_names)})")
        action = np.clip(LOW + (out - self._low) / self._span * (HIGH - LOW), LOW, HIGH)
        self.timings["policy"] += time.perf_counter() - t0
        return action, self._estimate.copy()
