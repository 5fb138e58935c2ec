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
    def live(self, rec: StepRecord) -> dict: ...


@dataclass(frozen=True)
class HumanMap:
    """How a world's action follows a person's inputs, as a driving game's steering does: both the steering's limit
    and how fast a held key moves it fall with speed, derived from the car's geometry (wheelbase, steer_lock).

    The lateral acceleration of a car turning at wheel angle delta at speed v is v^2 tan(delta) / wheelbase, so
    - full steering is at most the wheel angle that turns the car at `lateral_accel` m/s^2 (full lock when slow);
    - a held key builds that lateral acceleration at most `lateral_jerk` m/s^3: fast, full steering takes
      lateral_accel / lateral_jerk seconds, whatever the speed, and a tap of tau seconds leaves the car moving
      sideways at about lateral_jerk tau^2 / 2 m/s; slow, where that would be faster, the key's own rate
      (drivestudio/studio/human.py) holds.

    to_action(steer fraction of full lock, + right; throttle; brake) is the world's command."""

    lateral_accel: float      # [m/s^2] full steering turns the car at most this hard
    lateral_jerk: float       # [m/s^3] a held key builds the lateral acceleration at most this fast
    wheelbase: float          # [m]
    steer_lock: float         # [rad] wheel angle at full lock
    to_action: Callable[[float, float, float], np.ndarray]

    def steer_limit(self, speed: float) -> float:
        """The fraction of full lock that full steering gives at `speed` [m/s]."""
        v2 = max(speed * speed, 1e-6)
        return min(1.0, math.atan(self.lateral_accel * self.wheelbase / v2) / self.steer_lock)

    def full_lateral_accel(self, speed: float) -> float:
        """[m/s^2] how hard full steering turns the car at `speed` (lateral_accel, less when slow)."""
        return speed * speed * math.tan(self.steer_limit(speed) * self.steer_lock) / self.wheelbase

    def steer_rate(self, speed: float, key_rate: float) -> float:
        """How fast a held key moves the steering input [fraction of full steering per second] at `speed`: the
        key's own rate, or slower where that would build the lateral acceleration faster than lateral_jerk."""
        full = self.full_lateral_accel(abs(speed))
        return key_rate if full <= 0 else min(key_rate, self.lateral_jerk / full)

    def action(self, steer: float, throttle: float, brake: float, speed: float) -> np.ndarray:
        return self.to_action(steer * self.steer_limit(abs(speed)), throttle, brake)


@dataclass(frozen=True)
class StudioKit:
    """A world in the studio. scene_key: the setting of the world's configuration naming a scene (highway: track,
    sidewalk: path) and its default; presets: the names the page offers; view(world, scene ref): the page's view;
    note: what the labels panel's truth and bars are, in a line."""

    scene_key: str
    scene_default: str
    presets: Callable[[], list[str]]
    view: Callable[[Any, str], View]
    note: str
    human: HumanMap

    def scene(self, config) -> dict:
        """{scene_key: what the world's configuration names, "seed": ...} of the scene a world is built from."""
        return {self.scene_key: str(getattr(config, self.scene_key, None) or self.scene_default),
                "seed": int(config.seed)}

    def view_for(self, world, config) -> View:
        return self.view(world, self.scene(config)[self.scene_key])
