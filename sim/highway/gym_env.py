"""The world as a Gymnasium environment: `gymnasium.make("drivestudio/Highway-v0", track="oval", lanes=3)`.

Observation: the camera frame (height, width, 3) uint8. Action: [steer, accel, brake] in [-1, 1] x [0, 1] x
[0, 1] (steer positive left). info carries the ground truth: the 14 indicators by name, `indicators` as an
array in canonical order, lanes_left, lanes, speed and the poses. Reward: metres driven along the track in
the step, minus 50 on a collision and 5 per step off the road. An episode ends (terminated) on a collision
or when the car is lost off the road; it is truncated after `max_steps`.
"""
from __future__ import annotations

import gymnasium as gym
import numpy as np

from core.worlds.highway import FRAME, Action
from sim.camera import CameraConfig
from sim.highway.world import Observation, World, WorldConfig

COLLISION_PENALTY = 50.0
OFF_ROAD_PENALTY = 5.0


class HighwayEnv(gym.Env):
    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, track="oval", lanes: int | None = None, cars: int = 12, renderer: str = "tiny",
                 width: int = FRAME[1], height: int = FRAME[0], max_steps: int = 3000, start_speed: float = 15.0,
                 render_mode: str | None = "rgb_array"):
        camera = CameraConfig(width=width, height=height)
        self._config = WorldConfig(track=track, lanes=lanes, cars=cars, renderer=renderer, camera=camera,
                                   start_speed=start_speed)
        self._world: World | None = None
        self.dt = self._config.dt   # [s] simulated per step
        self.max_steps = max_steps
        self.render_mode = render_mode
        self.observation_space = gym.spaces.Box(0, 255, (height, width, 3), dtype=np.uint8)
        self.action_space = gym.spaces.Box(np.array([-1, 0, 0], dtype=np.float32),
                                           np.array([1, 1, 1], dtype=np.float32), dtype=np.float32)
        self._last: Observation | None = None
        self._steps = 0

    @staticmethod
    def _info(obs: Observation) -> dict:
        info = obs.truth.as_dict()
        info.update(indicators=obs.truth.indicators.copy(), t=obs.t, collision=obs.collision,
                    off_road=obs.off_road)
        return info

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**31 - 1))
        if self._world is None:
            self._config.seed = seed
            self._world = World(self._config)
            obs = self._world.observe()
        else:
            obs = self._world.reset(seed)
        self._last, self._steps = obs, 0
        return obs.frame, self._info(obs)

    def step(self, action):
        assert self._world is not None, "call reset() first"
        s_before = self._world.ego.s
        obs = self._world.step(Action.from_array(action))
        self._last = obs
        self._steps += 1
        reward = float(self._world.track.gap(s_before, self._world.ego.s))
        reward -= COLLISION_PENALTY * obs.collision + OFF_ROAD_PENALTY * obs.off_road
        terminated = bool(obs.collision or obs.lost)
        truncated = self._steps >= self.max_steps
        return obs.frame, reward, terminated, truncated, self._info(obs)

    def render(self):
        return None if self._last is None else self._last.frame

    def close(self):
        if self._world is not None:
            self._world.close()
            self._world = None
