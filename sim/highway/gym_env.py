"""The world as a Gymnasium environment: `gymnasium.make("drivestudio/Highway-v0", track="oval", lanes=3)`.

Observation (`observation=`): "camera" (default), the front camera's frame (height, width, 3) uint8;
"affordances", the exact values of the fields HIGHWAY marks observable as a float32 Box: the 14 indicators in
canonical order (docs/affordances.md) then the host car's speed [m/s], within BOUNDS below (nothing is rendered,
unless render() asks);
"both", a Dict of the frame ("front") and the affordances ("affordances").
Action: [steer, accel, brake] in [-1, 1] x [0, 1] x [0, 1] (steer positive left).
Reward, per step, the sum of four terms, also in info["reward_terms"]:
  progress   metres driven along the track in the step (negative when driving backwards)
  collision  -50 on every step the host car touches another car
  off_road   -5 on every step its centre is beyond a road edge
  lost       -50 on the step the car is lost off the road (the episode ends: as costly as a collision, so that
             leaving the road for good is never a way out of the off_road term)
An episode ends (terminated) on a collision or when the car is lost off the road (6 m beyond the edge); it is
truncated after `max_steps`. info carries the ground truth: the 14 indicators by name, `indicators` as an array in
canonical order, lanes_left, lanes, speed, the poses, collision, off_road and t.
`scenario=` (a scripted scenario file, docs/scenarios.md) replaces track, lanes and cars by its route: every reset
replays it, at its own seed, an episode is truncated at its end (or at max_steps, if sooner), and info["scenario"]
holds the events carried out and the verdict of its criteria so far.
`condition=` draws the frames in a named condition, or each reset's seed draws one of several ("clear,fog,night";
docs/conditions.md), then named in info["condition"]; the truth does not change with it.
Every option is checked here, before any SUMO starts; the world opens on the first reset().
"""
from __future__ import annotations

import math
import os
import weakref
from dataclasses import replace

import gymnasium as gym
import numpy as np

from core.conditions import SEEDED
from core.worlds.highway import GAP_INACTIVE, GAPS, HIGHWAY, INDICATORS, Action
from sim import gym_options as opt
from sim.highway.scripted import load_scripted
from sim.highway.sumo_traffic import car_count_problem
from sim.highway.vehicle import VehicleParams
from sim.highway.world import Observation, World, WorldConfig
from sim.track import load_track

ENV = "drivestudio/Highway-v0"
COLLISION_PENALTY = 50.0
OFF_ROAD_PENALTY = 5.0
LOST_PENALTY = 50.0
DEFAULTS = WorldConfig()   # the world's configuration: the keyword arguments' defaults, units and ranges
MAX_EPISODE = 1_000_000  # steps
MARKING_RANGE = 15.0     # [m] |toMarking_*| bound: 1.5 lanes of the widest lane and more (docs/affordances.md)

# the affordance observation's bounds: angle in [-pi, pi], distances to markings, gaps up to the inactive 75 m,
# fast 0/1, the speed up to the car's top speed (sim/highway/vehicle.py)
BOUNDS: dict[str, tuple[float, float]] = {
    "angle": (-math.pi, math.pi), "fast": (0.0, 1.0), "speed": (0.0, VehicleParams().top_speed),
    **{n: (-MARKING_RANGE, MARKING_RANGE) for n in INDICATORS if n.startswith("toMarking")},
    **{n: (0.0, GAP_INACTIVE) for n in GAPS},
}
AFFORDANCES = opt.Affordances(HIGHWAY, BOUNDS)


class HighwayEnv(gym.Env):
    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, track=DEFAULTS.track, lanes: int | None = DEFAULTS.lanes, cars: int = DEFAULTS.cars,
                 renderer: str = DEFAULTS.renderer, width: int = DEFAULTS.camera.width,
                 height: int = DEFAULTS.camera.height, max_steps: int = 3000,
                 start_speed: float = DEFAULTS.start_speed, render_mode: str | None = "rgb_array",
                 observation: str = "camera", scenario: str | None = None, condition: str = DEFAULTS.condition):
        self.observation = opt.check_choice(ENV, "observation", observation, opt.OBSERVATIONS)
        config = opt.check_settings(ENV, DEFAULTS, {
            "lanes": ("lanes", lanes), "cars": ("cars", cars), "renderer": ("renderer", renderer),
            "width": ("camera.width", width), "height": ("camera.height", height),
            "start_speed": ("start_speed", start_speed), "condition": ("condition", condition)})
        lanes, cars, width, height = config.lanes, config.cars, config.camera.width, config.camera.height
        self.max_steps = opt.check_int(ENV, "max_steps", max_steps, 1, MAX_EPISODE)
        if render_mode is not None:
            opt.check_choice(ENV, "render_mode", render_mode, tuple(self.metadata["render_modes"]))
        config = replace(config, track=track, render=self.observation != "affordances")
        if scenario is not None:
            config = self._scripted(config, scenario)
        else:
            try:
                road = load_track(track, lanes=lanes)
            except ValueError as e:   # TrackError: an unknown preset, a bad file, arcs too tight for the lanes
                raise opt.fail(ENV, "track" if lanes is None else "track/lanes", str(e)) from None
            problem = car_count_problem(road, cars)
            if problem:
                raise opt.fail(ENV, "cars", problem)
        self._config = config
        self.declaration = HIGHWAY.with_camera("front", height, width)
        self._world: World | None = None
        self._finalizer: weakref.finalize | None = None
        self.dt = self._config.dt   # [s] simulated per step
        self.render_mode = render_mode
        spaces: dict[str, gym.spaces.Space] = {"camera": gym.spaces.Box(0, 255, (height, width, 3), dtype=np.uint8),
                                               "affordances": AFFORDANCES.space,
                                               "both": opt.both_space(self.declaration, AFFORDANCES)}
        self.observation_space = spaces[self.observation]
        self.action_space = gym.spaces.Box(np.array([-1, 0, 0], dtype=np.float32),
                                           np.array([1, 1, 1], dtype=np.float32), dtype=np.float32)
        self._last: Observation | None = None
        self._steps = 0

    def _scripted(self, config: WorldConfig, scenario) -> WorldConfig:
        """The configuration with a scripted scenario's route; its episodes end with it."""
        if not isinstance(scenario, (str, os.PathLike)):
            raise opt.fail(ENV, "scenario", f"must be the path of a scenario file, got {scenario!r}")
        try:
            script = load_scripted(scenario)
        except ValueError as e:   # ScenarioError: one line naming the file and the field
            raise opt.fail(ENV, "scenario", str(e)) from None
        self.max_steps = min(self.max_steps, max(1, int(round(script.seconds / config.dt))))
        return script.configure(replace(config, scenario=str(scenario)))

    def _info(self, obs: Observation) -> dict:
        info = obs.truth.as_dict()
        info.update(indicators=obs.truth.indicators.copy(), t=obs.t, collision=obs.collision,
                    off_road=obs.off_road)
        report = self._world.scenario_report() if self._world is not None else None
        if report is not None:
            info["scenario"] = report
        if self._world is not None and self._config.condition != SEEDED:   # the one this reset's seed drew
            info["condition"] = self._world.condition
        return info

    def _observation(self, obs: Observation):
        if self.observation == "camera":
            return obs.frame
        if self.observation == "affordances":
            return AFFORDANCES(obs.record)
        return opt.both(self.declaration, AFFORDANCES, obs.frames, obs.record)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**31 - 1))
        if self._world is None:
            self._config.seed = seed
            self._world = World(self._config)
            # closed however the interpreter ends: SUMO and the pybullet client go before modules are torn down
            self._finalizer = weakref.finalize(self, self._world.close)
            obs = self._world.observe()
        else:
            obs = self._world.reset(seed)
        self._last, self._steps = obs, 0
        return self._observation(obs), self._info(obs)

    def step(self, action):
        if self._world is None:
            raise RuntimeError(f"{ENV}: call reset() before step()")
        s_before = self._world.ego.s
        obs = self._world.step(Action.from_array(opt.check_action(ENV, action, HIGHWAY)))
        self._last = obs
        self._steps += 1
        terms = {"progress": float(self._world.track.gap(s_before, self._world.ego.s)),
                 "collision": -COLLISION_PENALTY * obs.collision, "off_road": -OFF_ROAD_PENALTY * obs.off_road,
                 "lost": -LOST_PENALTY * obs.lost}
        reward = sum(terms.values())
        terminated = bool(obs.collision or obs.lost)
        truncated = self._steps >= self.max_steps
        info = self._info(obs)
        info["reward_terms"] = terms
        return self._observation(obs), reward, terminated, truncated, info

    def render(self):
        if self._last is None or self._world is None:
            return None
        if self._last.frame is None:   # the affordance observation renders nothing; draw this instant now
            self._last = self._world.observe(render=True)
        return self._last.frame

    def close(self):
        if self._finalizer is not None:
            self._finalizer()
            self._finalizer = None
        self._world = None
