"""A person at the controls: the keyboard's ramped inputs, a gamepad's axes, and the command they make in each world.

The page sends what is pressed (arrows or WASD) and, when a gamepad is connected, its axes (the browser's Gamepad
API); `HumanInput` turns them into three inputs, advanced once per simulated step:

- steer in [-1, 1] (+1 full right), a fraction of full steering. A held arrow moves it toward full steering at
  KEY_STEER_RATE per second when slow, as a real wheel or stick takes time to turn, and slower at speed (the
  world's HumanMap.steer_rate); released, or turned the other way, it goes back through the centre at
  KEY_CENTRE_RATE per second (self-centring), at any speed.
- throttle and brake in [0, 1]: rise at KEY_PEDAL_RATE per second while held, fall at KEY_PEDAL_RELEASE.
- A gamepad's axes (beyond GAMEPAD_DEADZONE) are used as they are, without a ramp: the stick is the ramp.

A world's `HumanMap` (drivestudio/studio/kit.py) turns the inputs into its action. Steering is speed-sensitive, as
a game's is: full steering is at most the wheel angle that turns the car at `lateral_accel` m/s^2 at its present
speed (full lock when slow), and a held key builds that turn at most `lateral_jerk` m/s^3, so that a tap at 20 m/s
nudges the car instead of sending it across the road.

The person "touches the controls" while a key is held or an axis is beyond the deadzone, and keeps them for
TAKEOVER_HOLD seconds after letting go (the inputs ramp back meanwhile): that is how long a take-over lasts.
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from drivestudio.loop import Percept
from drivestudio.studio.kit import HumanMap

KEY_STEER_RATE = 2.5      # [1/s] steering input toward full steering while an arrow is held, slow (0.4 s)
KEY_CENTRE_RATE = 5.0     # [1/s] toward the centre when released or countersteered
KEY_PEDAL_RATE = 2.0      # [1/s] throttle or brake rise while held (0.5 s to full)
KEY_PEDAL_RELEASE = 5.0   # [1/s] and fall when released
GAMEPAD_DEADZONE = 0.08   # axes smaller than this are at rest
TAKEOVER_HOLD = 0.5       # [s] a take-over lasts this long after the last touch


@dataclass(frozen=True)
class Keys:
    """What the page says is held: the arrows (or W A S D)."""

    left: bool = False
    right: bool = False
    up: bool = False
    down: bool = False

    @property
    def any(self) -> bool:
        return self.left or self.right or self.up or self.down


@dataclass(frozen=True)
class Pad:
    """A gamepad's axes: steer in [-1, 1] (+ right), throttle and brake in [0, 1]."""

    steer: float = 0.0
    throttle: float = 0.0
    brake: float = 0.0

    @property
    def active(self) -> bool:
        return max(abs(self.steer), self.throttle, self.brake) > GAMEPAD_DEADZONE


def _toward(value: float, target: float, rate: float, dt: float) -> float:
    step = rate * dt
    # within a rounding error of the target is on it (a ramp of whole steps lands exactly)
    return target if abs(target - value) <= step + 1e-12 else value + math.copysign(step, target - value)


def _steer(value: float, want: float, dt: float, rate: float = KEY_STEER_RATE) -> float:
    """The keyboard's steering after dt: toward `want` (-1, 0 or 1) at `rate`, through the centre at the centring
    rate."""
    if want == 0:
        return _toward(value, 0.0, KEY_CENTRE_RATE, dt)
    if value * want < 0:                 # turned the other way: back to the centre first
        centred = _toward(value, 0.0, KEY_CENTRE_RATE, dt)
        if centred != 0.0:
            return centred
        dt -= abs(value) / KEY_CENTRE_RATE   # the rest of the step ramps out
        if dt <= 1e-9:
            return 0.0
    return _toward(value if value * want > 0 else 0.0, want, rate, dt)


class HumanInput:
    """The latest keys and axes from the page (set by the server's thread) and the ramped inputs (advanced by the
    loop's thread, once per step)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._keys, self._pad = Keys(), Pad()
        self.steer = self.throttle = self.brake = 0.0
        self._since_touch = math.inf     # [s] simulated time since the controls were last touched

    def set(self, keys: Keys, pad: Pad | None) -> None:
        with self._lock:
            self._keys, self._pad = keys, pad or Pad()

    def release(self) -> None:
        """The page that held the controls went away: nothing is held any more."""
        self.set(Keys(), None)

    def advance(self, dt: float, steer_rate: float = KEY_STEER_RATE) -> tuple[float, float, float]:
        """Ramp the inputs over one step of dt seconds, a held arrow's steering at `steer_rate` per second; returns
        (steer, throttle, brake)."""
        with self._lock:
            keys, pad = self._keys, self._pad
        if pad.active:
            self.steer = float(np.clip(pad.steer, -1, 1)) if abs(pad.steer) > GAMEPAD_DEADZONE else 0.0
            self.throttle = float(np.clip(pad.throttle, 0, 1)) if pad.throttle > GAMEPAD_DEADZONE else 0.0
            self.brake = float(np.clip(pad.brake, 0, 1)) if pad.brake > GAMEPAD_DEADZONE else 0.0
        else:
            self.steer = _steer(self.steer, float(keys.right) - float(keys.left), dt, steer_rate)
            self.throttle = _toward(self.throttle, float(keys.up), KEY_PEDAL_RATE if keys.up else KEY_PEDAL_RELEASE,
                                    dt)
            self.brake = _toward(self.brake, float(keys.down), KEY_PEDAL_RATE if keys.down else KEY_PEDAL_RELEASE,
                                 dt)
        self._since_touch = 0.0 if keys.any or pad.active else self._since_touch + dt
        return self.steer, self.throttle, self.brake

    @property
    def touching(self) -> bool:
        """The person holds the controls now, or let go less than TAKEOVER_HOLD ago (as of the last advance)."""
        return self._since_touch < TAKEOVER_HOLD - 1e-9


class HumanDriver:
    """The person as a Driver (drivestudio/loop.py): act() returns the command of the latest inputs from the page,
    advanced by one step at the car's present speed. It has no estimate (NaN)."""

    name = "human"

    def __init__(self, human_map: HumanMap, dt: float, n_estimate: int, speed_index: int, controls: HumanInput):
        self.map, self.dt, self.controls = human_map, dt, controls
        self._speed = speed_index
        self._no_estimate = np.full(n_estimate, np.nan)
        self.timings = {"control": 0.0}

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        speed = float(percept.record[self._speed])
        steer, throttle, brake = self.controls.advance(self.dt, self.map.steer_rate(speed, KEY_STEER_RATE))
        return self.map.action(steer, throttle, brake, speed), self._no_estimate
