"""What a world gives the studio (drivestudio/studio/): the option that names its scene and its presets, the view
that draws it for the page, and how a person's inputs become its command. Each world's own module builds its kit
(drivestudio/worlds/<world>/studio.py); the studio names no world."""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from drivestudio.loop import StepRecord


def finite(x) -> float | None:
    """A number for JSON: None for NaN and infinities."""
    x = float(x)
    return x if math.isfinite(x) else None


def label_row(name: str, unit: str, truth, estimate, scale: float) -> dict:
    """One row of the labels panel: truth, estimate, and the error that fills its bar."""
    return {"name": name, "unit": unit, "truth": finite(truth), "estimate": finite(estimate), "scale": scale}


class View(Protocol):
    """What the page shows of a world. `capture` runs in the loop's thread on every published step and only keeps
    references (a world's observations are new objects every step); `images` draws, in the encoder's thread."""

    cameras: tuple[str, ...]

    def capture(self, rec: StepRecord, driver_name: str) -> dict: ...
    def images(self, snap: dict) -> list[tuple[str, np.ndarray]]: ...
    def labels(self, rec: StepRecord) -> list[dict]: ...
    def controller(self, driver, supervisor, rec: StepRecord) -> dict: ...
    def columns(self, rec: StepRecord, who: str) -> dict: ...
    def metrics(self, report: dict) -> dict: ...


@dataclass(frozen=True)
class HumanMap:
    """How a world's action follows a person's inputs. steer_lock [rad] and wheelbase [m] make the speed-sensitive
    limit; to_action(steer fraction of full lock, + right; throttle; brake) is the world's command."""

    lateral_accel: float      # [m/s^2] full steering turns the car at most this hard
    wheelbase: float          # [m]
    steer_lock: float         # [rad] wheel angle at full lock
    to_action: Callable[[float, float, float], np.ndarray]

    def steer_limit(self, speed: float) -> float:
        """The fraction of full lock that full steering gives at `speed` [m/s]."""
        v2 = max(speed * speed, 1e-6)
        return min(1.0, math.atan(self.lateral_accel * self.wheelbase / v2) / self.steer_lock)

    def action(self, steer: float, throttle: float, brake: float, speed: float) -> np.ndarray:
        return self.to_action(steer * self.steer_limit(abs(speed)), throttle, brake)


@dataclass(frozen=True)
class StudioKit:
    """A world in the studio. scene_key: the option naming a scene (highway: track, sidewalk: path) and its
    default; presets: the names the page offers; view(world, scene ref): the page's view; note: what the labels
    panel's truth and bars are, in a line."""

    scene_key: str
    scene_default: str
    presets: Callable[[], list[str]]
    view: Callable[[Any, str], View]
    note: str
    human: HumanMap

    def scene(self, args) -> dict:
        """{scene_key: what the options name, "seed": ...} of the scene a world is built from."""
        return {self.scene_key: getattr(args, self.scene_key, None) or self.scene_default,
                "seed": int(getattr(args, "seed", 0) or 0)}

    def view_for(self, world, args) -> View:
        return self.view(world, self.scene(args)[self.scene_key])
