"""The options of the Gymnasium environments, checked in their constructors, before anything is started.

`gymnasium.make("drivestudio/Highway-v0", observation="pixels")` raises one EnvOptionError (a ValueError) that
names the environment, the option and what it accepts, and no SUMO, renderer or world is left half-started: the
environments open their worlds only in reset(). The observation kinds and how an observation is built from a
world's frames and truth record are here too, shared by both worlds.
"""
from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

from core.declaration import WorldDeclaration
from core.settings import SettingError, check_value, entries, with_values

OBSERVATIONS = ("camera", "affordances", "both")
AFFORDANCES = "affordances"   # the key of the affordance vector in a "both" observation
MIN_SIDE, MAX_SIDE = 16, 4096   # [px] a camera's width and height, as the CLI's --width and --height


class EnvOptionError(ValueError):
    """An option given to gymnasium.make that the environment cannot use; the message names it."""


def fail(env: str, option: str, message: str) -> EnvOptionError:
    return EnvOptionError(f"{env}: option {option}: {message}")


def check_settings(env: str, config, values: dict):
    """`config` (a world's configuration, core/settings.py) with `values`, {keyword: (setting path, value)}, each
    held to its setting: the keyword arguments of gymnasium.make take their defaults, units and ranges from the
    world's configuration."""
    table = entries(type(config))
    out = {}
    for keyword, (path, value) in values.items():
        try:
            out[path] = check_value(table[path], value, "")
        except SettingError as e:
            raise fail(env, keyword, str(e).lstrip(": ")) from None
    return with_values(config, out)


def check_choice(env: str, option: str, value, choices: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise fail(env, option, f"must be one of {', '.join(choices)}, got {value!r}")
    return value


def check_int(env: str, option: str, value, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
        raise fail(env, option, f"must be an integer from {low} to {high}, got {value!r}")
    return int(value)


def check_number(env: str, option: str, value, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or \
            not (math.isfinite(value) and low <= value <= high):
        raise fail(env, option, f"must be a number from {low:g} to {high:g}, got {value!r}")
    return float(value)


def check_side(env: str, option: str, value) -> int:
    return check_int(env, option, value, MIN_SIDE, MAX_SIDE)


class EnvActionError(ValueError):
    """An action given to step() that is not the environment's: of another length, not numbers, or not finite."""


def check_action(env: str, action, decl: WorldDeclaration) -> np.ndarray:
    """The action as float64 numbers in the declaration's order; EnvActionError naming the expected action and
    what was given otherwise. A NaN or an infinity is refused: the world would read it as a neutral command or
    carry it into the car's state, and the policy that produced it would go on unaware."""
    names = decl.action_names
    expected = f"{len(names)} numbers ({', '.join(names)})"
    try:
        raw = np.asarray(action)
    except ValueError:   # a ragged nesting of lists
        raw = np.asarray(None)
    if raw.dtype.kind not in "biuf":   # None, strings, objects: not numbers (numpy would read None as NaN)
        raise EnvActionError(f"{env}: step() takes an action of {expected}, got {action!r}")
    values = raw.astype(np.float64)
    if values.size != len(names):
        shown = np.array2string(values.ravel()[:8], separator=", ") + (" ..." if values.size > 8 else "")
        raise EnvActionError(f"{env}: step() takes an action of {expected}, got {values.size} "
                             f"number{'' if values.size == 1 else 's'}: {shown}")
    values = values.reshape(len(names))
    bad = [f"{n}={v}" for n, v in zip(names, values.tolist()) if not math.isfinite(v)]
    if bad:
        raise EnvActionError(f"{env}: step() takes finite numbers ({', '.join(names)}), got {', '.join(bad)}")
    return values


# --- observations ----------------------------------------------------------------------------------------------
class Affordances:
    """The affordance observation of a world: the exact values of the fields its declaration marks observable, in
    its order, float32, in a Box with finite bounds (`bounds`: {field: (low, high)}, one per observable field).
    A value beyond its bounds (only a car far off its road gets there) is clipped to them. The environment and a
    policy driver (drivestudio/worlds/highway/policy.py) both build observations here, so they read the same."""

    def __init__(self, decl: WorldDeclaration, bounds: dict[str, tuple[float, float]]):
        missing = [n for n in decl.observable if n not in bounds]
        if missing or not decl.observable:
            raise ValueError(f"world {decl.name!r}: no bounds for observable fields {missing}")
        self.names = decl.observable
        self._index = [decl.index(n) for n in self.names]
        self.low = np.array([bounds[n][0] for n in self.names], dtype=np.float32)
        self.high = np.array([bounds[n][1] for n in self.names], dtype=np.float32)
        self.space = gym.spaces.Box(self.low, self.high, dtype=np.float32)

    def __call__(self, record) -> np.ndarray:
        values = np.asarray(record, dtype=np.float64)[..., self._index].astype(np.float32)
        return np.clip(values, self.low, self.high)


def camera_spaces(decl: WorldDeclaration) -> dict[str, gym.spaces.Box]:
    """One uint8 image space per camera of the declaration, by the camera's name."""
    return {c.name: gym.spaces.Box(0, 255, c.shape, dtype=np.uint8) for c in decl.cameras}


def both_space(decl: WorldDeclaration, view: Affordances) -> gym.spaces.Dict:
    """Every camera's image by its name and the affordances, in one Dict: each entry an image or a vector, which
    Stable-Baselines3's MultiInputPolicy reads without a wrapper."""
    return gym.spaces.Dict({**camera_spaces(decl), AFFORDANCES: view.space})


def both(decl: WorldDeclaration, view: Affordances, frames, record) -> dict[str, np.ndarray]:
    return {**{c.name: f for c, f in zip(decl.cameras, frames)}, AFFORDANCES: view(record)}
