"""The sidewalk world as a Gymnasium environment: `gymnasium.make("drivestudio/Sidewalk-v0", mode="direct")`.

Observation: the stereo pair, uint8 (2, height, width, 3): left then right. Action: [steer, motor] in [0, 1]^2
(steer 0.5 straight, 1 full right; motor 0.5 stop, 1 full speed forward). info: the truth record by name
(SIDEWALK's fields, core/worlds/sidewalk.py), `record` (the same as an array) and t. Reward: metres driven
along the path in the step, minus 10 on the step a collision begins and 1 per step off the path. An episode ends
(terminated) when the car is lost off the path; it is truncated after `max_steps` (9000: 5 minutes).
reset(options={"mode": "follow"}) switches the behavioural mode.
"""
from __future__ import annotations

import gymnasium as gym
import numpy as np

from core.worlds.sidewalk import SIDEWALK
from sim.sidewalk.stereo import StereoConfig
from sim.sidewalk.world import Observation, SidewalkConfig, SidewalkWorld, check_mode

COLLISION_PENALTY = 10.0
OFF_PATH_PENALTY = 1.0


class SidewalkEnv(gym.Env):
    metadata = {"render_modes": ["rgb_array"], "render_fps": 30}

    def __init__(self, path="park", mode: str = "direct", obstacles=4.0, width: int = 336, height: int = 188,
                 max_steps: int = 9000, render_mode: str | None = "rgb_array"):
        self.path, self.mode, self.obstacles = path, check_mode(mode), obstacles
        self.stereo = StereoConfig(width=width, height=height)
        self.max_steps = max_steps
        self.render_mode = render_mode
        self.observation_space = gym.spaces.Box(0, 255, (2, height, width, 3), dtype=np.uint8)
        self.action_space = gym.spaces.Box(np.zeros(2, np.float32), np.ones(2, np.float32), dtype=np.float32)
        self._world: SidewalkWorld | None = None
        self._last: Observation | None = None
        self._steps = 0
        self._i = {n: SIDEWALK.index(n) for n in ("s", "collision", "off_path")}

    def _info(self, obs: Observation) -> dict:
        return {**obs.truth, "record": obs.record.copy(), "t": obs.t}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**31 - 1))
        mode = check_mode((options or {}).get("mode", self.mode))
        if self._world is not None:
            self._world.close()
        self._world = SidewalkWorld(SidewalkConfig(path=self.path, seed=seed, mode=mode, obstacles=self.obstacles,
                                                   stereo=self.stereo))
        obs = self._world.observe(True)
        self._last, self._steps = obs, 0
        return np.stack(obs.frames), self._info(obs)

    def step(self, action):
        assert self._world is not None and self._last is not None, "call reset() first"
        before = self._last.record
        obs = self._world.step(np.asarray(action, dtype=np.float64), True)
        self._steps += 1
        track = self._world.path.track
        reward = float(track.gap(before[self._i["s"]], obs.record[self._i["s"]]))
        if obs.record[self._i["collision"]] and not before[self._i["collision"]]:
            reward -= COLLISION_PENALTY
        reward -= OFF_PATH_PENALTY * float(obs.record[self._i["off_path"]])
        self._last = obs
        return (np.stack(obs.frames), reward, obs.end is not None, self._steps >= self.max_steps,
                self._info(obs))

    def render(self):
        return None if self._last is None else np.concatenate(self._last.frames, axis=1)

    def close(self):
        if self._world is not None:
            self._world.close()
            self._world = None
