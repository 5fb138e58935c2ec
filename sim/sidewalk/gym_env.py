"""The sidewalk world as a Gymnasium environment: `gymnasium.make("drivestudio/Sidewalk-v0", mode="direct")`.

Observation (`observation=`): "camera" (default), the stereo pair, uint8 (2, height, width, 3): left then right;
"affordances", the exact values of the fields SIDEWALK marks observable as a float32 Box (core/worlds/sidewalk.py,
docs/gymnasium.md): steer, motor, behaviour, speed, d, heading, path_width, curvature, curvature_ahead,
border_left, border_right, obstacle_gap, obstacle_d, obstacle_width, lead_gap, lead_d, lead_speed, obstacle_near,
within BOUNDS below (nothing is rendered, unless render() asks); "both", a Dict of "left", "right" (each
(height, width, 3)) and "affordances".
Action: [steer, motor] in [0, 1]^2 (steer 0.5 straight, 1 full right; motor 0.5 stop, 1 full speed forward).
Reward, per step, the sum of three terms, also in info["reward_terms"]:
  progress   metres driven along the path in the step (negative when reversing)
  collision  -10 on the step a collision begins
  off_path   -1 on every step the car's centre is beyond the path's edge
An episode ends (terminated) when the car is lost off the path; it is truncated after `max_steps` (9000: 5
minutes). info: the truth record by name (SIDEWALK's fields), `record` (the same as an array) and t.
reset(options={"mode": "follow"}) switches the behavioural mode. Every option is checked here, before any world
is built.
"""
from __future__ import annotations

import math
import weakref

import gymnasium as gym
import numpy as np

from core.worlds.sidewalk import MODES, SIDEWALK, TOP_SPEED
from sim import gym_options as opt
from sim.sidewalk.layout import build_layout
from sim.sidewalk.paths import load_path
from sim.sidewalk.stereo import StereoConfig
from sim.sidewalk.world import Observation, SidewalkConfig, SidewalkWorld

ENV = "drivestudio/Sidewalk-v0"
COLLISION_PENALTY = 10.0
OFF_PATH_PENALTY = 1.0
MAX_EPISODE = 1_000_000  # steps
FAR = 30.0               # [m] obstacle_gap and lead_gap when nothing is ahead (core/worlds/sidewalk.py)
NO_BORDER = 5.0          # [m] border clearance where there is none

# the affordance observation's bounds: commands in [0, 1], the mode index, speeds up to the top speed either way,
# offsets within a lost car's reach, curvatures up to the tightest arc a path allows and beyond, gaps from alongside
# (negative) to FAR
BOUNDS: dict[str, tuple[float, float]] = {
    "steer": (0.0, 1.0), "motor": (0.0, 1.0), "behaviour": (0.0, len(MODES) - 1.0), "obstacle_near": (0.0, 1.0),
    "speed": (-TOP_SPEED, TOP_SPEED), "lead_speed": (-TOP_SPEED, TOP_SPEED), "heading": (-math.pi, math.pi),
    "d": (-10.0, 10.0), "path_width": (0.0, 10.0), "curvature": (-10.0, 10.0), "curvature_ahead": (-10.0, 10.0),
    "border_left": (-NO_BORDER, NO_BORDER), "border_right": (-NO_BORDER, NO_BORDER),
    "obstacle_gap": (-FAR, FAR), "obstacle_d": (-10.0, 10.0), "obstacle_width": (0.0, 10.0),
    "lead_gap": (-FAR, FAR), "lead_d": (-10.0, 10.0),
}
AFFORDANCES = opt.Affordances(SIDEWALK, BOUNDS)


class SidewalkEnv(gym.Env):
    metadata = {"render_modes": ["rgb_array"], "render_fps": 30}

    def __init__(self, path="park", mode: str = "direct", obstacles=4.0, width: int = 336, height: int = 188,
                 max_steps: int = 9000, render_mode: str | None = "rgb_array", observation: str = "camera"):
        self.observation = opt.check_choice(ENV, "observation", observation, opt.OBSERVATIONS)
        self.mode = opt.check_choice(ENV, "mode", mode, MODES)
        width, height = opt.check_side(ENV, "width", width), opt.check_side(ENV, "height", height)
        self.max_steps = opt.check_int(ENV, "max_steps", max_steps, 1, MAX_EPISODE)
        if render_mode is not None:
            opt.check_choice(ENV, "render_mode", render_mode, tuple(self.metadata["render_modes"]))
        try:
            self.path = load_path(path)
        except ValueError as e:   # PathError: an unknown preset, a bad file
            raise opt.fail(ENV, "path", str(e)) from None
        try:
            build_layout(self.path, 0, obstacles)   # a density out of range or a bad obstacle file, now
        except ValueError as e:
            raise opt.fail(ENV, "obstacles", str(e)) from None
        self.obstacles = obstacles
        self.stereo = StereoConfig(width=width, height=height)
        self.declaration = SIDEWALK.with_camera("left", height, width).with_camera("right", height, width)
        self.render_mode = render_mode
        spaces: dict[str, gym.spaces.Space] = {"camera": gym.spaces.Box(0, 255, (2, height, width, 3), dtype=np.uint8),
                                               "affordances": AFFORDANCES.space,
                                               "both": opt.both_space(self.declaration, AFFORDANCES)}
        self.observation_space = spaces[self.observation]
        self.action_space = gym.spaces.Box(np.zeros(2, np.float32), np.ones(2, np.float32), dtype=np.float32)
        self._world: SidewalkWorld | None = None
        self._finalizer: weakref.finalize | None = None
        self._last: Observation | None = None
        self._steps = 0
        self._render = self.observation != "affordances"
        self._i = {n: SIDEWALK.index(n) for n in ("s", "collision", "off_path")}

    def _info(self, obs: Observation) -> dict:
        return {**obs.truth, "record": obs.record.copy(), "t": obs.t}

    def _observation(self, obs: Observation):
        if self.observation == "camera":
            return np.stack(obs.frames)
        if self.observation == "affordances":
            return AFFORDANCES(obs.record)
        return opt.both(self.declaration, AFFORDANCES, obs.frames, obs.record)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**31 - 1))
        mode = opt.check_choice(ENV, "mode (of reset's options)", (options or {}).get("mode", self.mode), MODES)
        self.close()
        self._world = SidewalkWorld(SidewalkConfig(path=self.path, seed=seed, mode=mode, obstacles=self.obstacles,
                                                   stereo=self.stereo, render=self._render))
        # closed however the interpreter ends, before modules are torn down
        self._finalizer = weakref.finalize(self, self._world.close)
        obs = self._world.observe(self._render)
        self._last, self._steps = obs, 0
        return self._observation(obs), self._info(obs)

    def step(self, action):
        if self._world is None or self._last is None:
            raise RuntimeError(f"{ENV}: call reset() before step()")
        before = self._last.record
        obs = self._world.step(opt.check_action(ENV, action, SIDEWALK), self._render)
        self._steps += 1
        track = self._world.path.track
        started = bool(obs.record[self._i["collision"]]) and not before[self._i["collision"]]
        terms = {"progress": float(track.gap(before[self._i["s"]], obs.record[self._i["s"]])),
                 "collision": -COLLISION_PENALTY * started,
                 "off_path": -OFF_PATH_PENALTY * float(obs.record[self._i["off_path"]])}
        self._last = obs
        info = self._info(obs)
        info["reward_terms"] = terms
        return (self._observation(obs), terms["progress"] + terms["collision"] + terms["off_path"],
                obs.end is not None, self._steps >= self.max_steps, info)

    def render(self):
        if self._last is None or self._world is None:
            return None
        if self._last.frames[0] is None:   # the affordance observation renders nothing; draw this instant now
            self._last = self._world.observe(True)
        return np.concatenate(self._last.frames, axis=1)

    def close(self):
        if self._finalizer is not None:
            self._finalizer()
            self._finalizer = None
        self._world = None
