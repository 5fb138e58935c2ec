"""A small second world, declared by a test: a cart in a corridor seen by two cameras, with its own labels, its own
action and data moments that reach back one step and ahead two. It touches no generic code: the declaration, a
world, an expert and a Plugin here, plus a tiny model family, are all the generic machinery needs (docs/
architecture.md walks through it).

The cart drives along a straight corridor; `offset` [m] is its distance left of the centre line, `yaw` [rad] its
heading relative to the corridor. Each camera sees a bright vertical stripe (the corridor's centre line) whose
column moves with the offset, the right camera's by a fixed disparity. The expert steers back to the centre.

Used by other processes too (generate's workers, the driver of `drive`): they find it through
DRIVESTUDIO_WORLDS=tests.drivestudio.tiny_world:Plugin, with the repository as the working directory.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from core.declaration import Camera, Control, Label, Moment, Quantity, WorldDeclaration
from core.settings import MAX_SEED, setting
from drivestudio.worlds import Episode
from drivestudio.worlds import Plugin as BasePlugin
from perception import models

H, W = 12, 20          # [px] each camera's image
DISPARITY = 3          # [px] the right camera sees the stripe this far to the left
SPEED = 2.0            # [m/s]

TINY = WorldDeclaration(
    name="corridor", title="a cart in a corridor (a test's world)", dt=0.1,
    cameras=(Camera("near", H, W), Camera("far", H, W)),
    labels=(Label("turn", "-", "the command's turn", 0.5, 0.5), Label("go", "-", "the command's throttle"),
            Label("offset", "m", "left of the centre", 0.25, 0.5)),
    truth=(Quantity("turn", "-", "turn applied"), Quantity("go", "-", "throttle applied"),
           Quantity("offset", "m", "left of the centre", "f64"), Quantity("yaw", "rad", "heading", "f64"),
           Quantity("bumped", "0/1", "touched a wall", "bool")),
    action=(Control("turn", "-", "+1 full left", -1.0, 1.0, 0.0), Control("go", "-", "throttle", 0.0, 1.0, 0.0)),
    moment=Moment(instants=(-1, 0), horizon=2),
    targets=("turn", "go"),
)


class Observation:
    def __init__(self, frames, record, t, end=None):
        self.frames, self.record, self.t, self.end = frames, record, t, end


class Corridor:
    """The world: observe / step / recover / close, as drivestudio/loop.py wants."""

    declaration = TINY
    dt = TINY.dt

    def __init__(self, offset: float = 0.0, seed: int = 0):
        self.offset, self.yaw, self.t, self.turn, self.go = float(offset), 0.0, 0.0, 0.0, 0.0
        self.rng = np.random.default_rng(seed)
        self.timings = {"render": 0.0, "physics": 0.0}

    def _image(self, shift: int) -> np.ndarray:
        img = np.full((H, W, 3), 40, np.uint8)
        col = int(round(W / 2 + 4 * self.offset)) - shift   # the centre line moves right as the cart moves left
        if 0 <= col < W:
            img[:, col] = (250, 250, 250)
        return img

    def observe(self, render=True) -> Observation:
        t0 = time.perf_counter()
        frames = (self._image(0), self._image(DISPARITY)) if render or render is None else (None, None)
        self.timings["render"] += time.perf_counter() - t0
        bumped = abs(self.offset) > 2.0
        record = np.array([self.turn, self.go, self.offset, self.yaw, float(bumped)])
        return Observation(frames, record, self.t, "bumped into a wall" if abs(self.offset) > 3.0 else None)

    def step(self, action, render=True) -> Observation:
        t0 = time.perf_counter()
        turn, go = TINY.clip_action(action)
        self.turn, self.go = float(turn), float(go)
        self.yaw += 0.5 * self.turn * self.dt
        self.offset += SPEED * go * math.sin(self.yaw) * self.dt
        self.t += self.dt
        self.timings["physics"] += time.perf_counter() - t0
        return self.observe(render)

    def recover(self) -> None:
        self.offset, self.yaw = 0.0, 0.0

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class Expert:
    """Steers back to the centre line, wobbling a little (so that the data covers more than the centre)."""

    name = "expert"

    def __init__(self, seed: int = 0):
        self.rng = np.random.default_rng(seed)
        self.timings = {"control": 0.0}

    def act(self, percept):
        offset, yaw = percept.record[2], percept.record[3]
        turn = float(np.clip(-1.5 * offset - 3.0 * yaw + 0.3 * self.rng.standard_normal(), -1, 1))
        return np.array([turn, 1.0]), np.full(len(TINY.estimate_names), np.nan)


class Metrics:
    def __init__(self):
        self.steps, self.bumps, self.wall_time, self.times = 0, 0, 0.0, {}
        self.max_offset = 0.0

    def observe(self, obs) -> None:
        self.steps += 1
        self.bumps += int(obs.record[4])
        self.max_offset = max(self.max_offset, abs(obs.record[2]))

    def add_time(self, stage, seconds) -> None:
        self.times[stage] = self.times.get(stage, 0.0) + seconds

    def report(self) -> dict:
        return {"steps": self.steps, "bumps": self.bumps, "max_offset_m": round(self.max_offset, 3)}

    def table(self) -> str:
        return "\n".join(["| metric | value |", "|---|---|"] + [f"| {k} | {v} |" for k, v in self.report().items()])


@dataclass
class CorridorConfig:
    """The corridor's configuration: its settings are the verbs' options (core/settings.py)."""

    start_offset: float = setting(0.0, "offset at the start", unit="m", low=-2.0, high=2.0)
    seed: int = setting(0, "seed of the corridor", low=0, high=MAX_SEED)
    render: bool = True


class Plugin(BasePlugin):
    declaration = TINY
    expert_names = ("expert",)
    config_type = CorridorConfig
    verb_settings = {"drive": ("start_offset", "seed"), "serve": ("start_offset", "seed"),
                     "generate": ("start_offset",)}

    def world(self, config):
        return Corridor(config.start_offset, config.seed)

    def driver(self, spec, device="cpu", declaration=None, seed=0):
        return Expert(0) if spec.source == "expert" else super().driver(spec, device, declaration, seed)

    def metrics(self, world):
        return Metrics()

    def generate_options(self, config, plan) -> dict:
        return {"start_offset": config.start_offset}

    def plan(self, options, frames, episode_frames, seed):
        n = -(-frames // episode_frames)
        return [Episode(k, min(episode_frames, frames - k * episode_frames), seed * 100 + k,
                        {"start": options["start_offset"] + (k % 3 - 1) * 0.8}) for k in range(n)]

    def episode(self, ep, options, renderer):
        return Corridor(ep.params["start"], ep.seed), Expert(ep.seed), lambda obs: {}


# --- a tiny model family: one convolution and a linear layer, for any world's samples -----------------------------
class TinyConv(nn.Module):
    def __init__(self, channels: int, height: int, width: int, outputs: int):
        super().__init__()
        self.conv = nn.Conv2d(channels, 8, 3, padding=1)
        self.head = nn.Linear(8 * height * width, outputs)

    def forward(self, x, modes=None):
        return self.head(torch.relu(self.conv(x)).flatten(1))


models.register(models.Family(
    "tinyconv", "TinyConv (a test's model)", lambda inp, outputs, options: TinyConv(inp.channels, inp.height,
                                                                                    inp.width, outputs),
    fits=lambda decl: None, trainer="sgd", defaults={"iterations": 100, "batch_size": 8, "lr": 1e-2}))
