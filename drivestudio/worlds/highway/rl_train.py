"""Train a reinforcement-learning driver of the highway with Stable-Baselines3 (the optional `rl` extra).

    drivestudio ppo --minutes 18 --out runs/ppo-highway.zip
    drivestudio benchmark --model runs/ppo-highway.zip          # its row of the leaderboard, beside the oracle's

PPO on drivestudio/Highway-v0's affordance observation (the 14 indicators and the speed: no pixels, so nothing is
rendered and a world steps about 2,000 times a second) and the environment's own reward (docs/gymnasium.md), in the
world's own action space (Stable-Baselines3 clips the Gaussian policy's samples into it: a first policy coasts,
pressing a pedal half the time). Each episode drives another of the tracks `generate` records datasets on (the
presets and procedural:0-2, 1 to 3 lanes, 12 to 30 cars), none of the benchmark's default routes, and ends when the
car has been off the road for OFF_ROAD_LIMIT, with the environment's `lost` term: a car standing beside the road
would otherwise collect the off_road term for the rest of a long episode and teach nothing. Training stops after
--minutes of wall time or --steps, whichever comes first, and the model is saved (a .zip that
`drivestudio benchmark --model` accepts).
"""
from __future__ import annotations

import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import sim  # noqa: F401  registers drivestudio/Highway-v0
from sim.highway.gym_env import LOST_PENALTY
from sim.track import preset_names

TRACKS = tuple(preset_names()) + ("procedural:0", "procedural:1", "procedural:2")
LANES = (1, 3)        # lane counts drawn per episode, inclusive (generate's default plan: 1, 2, 3)
CARS = (12, 30)       # AI cars drawn per episode, inclusive (generate's default: 12-30)
EPISODE_STEPS = 1000  # 100 simulated seconds
OFF_ROAD_LIMIT = 20   # steps (2 s) off the road that end a training episode
# PPO as Stable-Baselines3's defaults for continuous control, with a smaller network (15 inputs) and a larger
# batch, which keeps the update cheap next to the simulation
ROLLOUT = 2048        # steps per update
BATCH = 256


class VariedHighway(gym.Env):
    """drivestudio/Highway-v0 on the affordance observation, another track, lane count and traffic each episode
    (drawn from `seed`), so a policy learns the indicators rather than one road."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, seed: int = 0, max_steps: int = EPISODE_STEPS):
        self._rng = np.random.default_rng(seed)
        self._max_steps = max_steps
        self._env: gym.Env | None = None
        self._off_road = 0
        probe = gym.make("drivestudio/Highway-v0", observation="affordances", cars=0)
        self.observation_space, self.action_space = probe.observation_space, probe.action_space
        probe.close()

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        if self._env is not None:
            self._env.close()
        while True:   # a draw whose lanes do not fit the track's bends, or whose cars do not fit, is drawn again
            track = str(self._rng.choice(TRACKS))
            lanes, cars = int(self._rng.integers(LANES[0], LANES[1] + 1)), int(self._rng.integers(CARS[0], CARS[1] + 1))
            try:
                self._env = gym.make("drivestudio/Highway-v0", track=track, lanes=lanes, cars=cars,
                                     observation="affordances", max_steps=self._max_steps).unwrapped
                break
            except ValueError:
                continue
        self._off_road = 0
        return self._env.reset(seed=int(self._rng.integers(0, 2**31 - 1)))

    def step(self, action):
        assert self._env is not None, "call reset() first"
        obs, reward, terminated, truncated, info = self._env.step(action)
        self._off_road = self._off_road + 1 if info["off_road"] else 0
        if self._off_road >= OFF_ROAD_LIMIT and not terminated:
            reward = float(reward) - LOST_PENALTY   # as the environment scores a car lost off the road
            info["reward_terms"]["lost"] = -LOST_PENALTY
            terminated = True
        return obs, reward, terminated, truncated, info

    def render(self):
        return None if self._env is None else self._env.render()

    def close(self):
        if self._env is not None:
            self._env.close()
            self._env = None


def make_env(seed: int) -> gym.Env:
    """The training environment: VariedHighway, episode statistics recorded."""
    return gym.wrappers.RecordEpisodeStatistics(VariedHighway(seed))


def train(minutes: float, steps: int, out: Path, seed: int = 0, log=print) -> dict:
    """Train PPO for `minutes` of wall time or `steps` environment steps; save to `out`; what happened."""
    import torch  # lazy: torch and Stable-Baselines3 (an optional extra) only when training
    from stable_baselines3 import PPO  # lazy: as torch
    from stable_baselines3.common.callbacks import BaseCallback  # lazy: as torch
    from stable_baselines3.common.logger import Logger  # lazy: as torch

    from drivestudio.worlds.highway.policy_features import ScaledBox  # lazy: it imports torch

    torch.set_num_threads(1)   # the simulation and a 64-unit network: one thread is fastest, and shares the machine
    env = make_env(seed)
    rollout = min(ROLLOUT, 1 << max(6, steps.bit_length() - 1))   # a smoke run of a few hundred steps updates too
    model = PPO("MlpPolicy", env, seed=seed, device="cpu", verbose=0, n_steps=rollout, batch_size=min(BATCH, rollout),
                n_epochs=10, learning_rate=3e-4, gamma=0.99, gae_lambda=0.95, clip_range=0.2, ent_coef=0.0,
                # log_std -1: a first policy that steers within about a third of full lock, not across it, stays
                # on the road long enough to find out that driving on earns more than leaving
                policy_kwargs={"features_extractor_class": ScaledBox, "net_arch": [64, 64], "log_std_init": -1.0})
    # a logger with no outputs: Stable-Baselines3's own, even silent, makes an empty folder in /tmp every run
    model.set_logger(Logger(folder=None, output_formats=[]))
    t0 = time.perf_counter()
    returns: list[float] = []

    class Budget(BaseCallback):
        """Stops at the wall-time budget; collects episode returns; reports every rollout."""

        def _on_step(self) -> bool:
            for info in self.locals.get("infos", ()):
                if "episode" in info:
                    returns.append(float(info["episode"]["r"]))
            return time.perf_counter() - t0 < minutes * 60

        def _on_rollout_end(self) -> None:
            recent = returns[-20:]
            log(f"{self.num_timesteps} steps, {time.perf_counter() - t0:.0f} s, {len(returns)} episodes, "
                f"mean return of the last {len(recent)}: {np.mean(recent) if recent else float('nan'):.1f}")

    model.learn(total_timesteps=steps, callback=Budget())
    wall = time.perf_counter() - t0
    out.parent.mkdir(parents=True, exist_ok=True)
    model.save(out)
    env.close()
    recent = returns[-20:]
    return {"steps": int(model.num_timesteps), "wall_s": round(wall, 1), "episodes": len(returns),
            "steps_per_s": round(model.num_timesteps / wall, 1),
            "mean_return_last_20": round(float(np.mean(recent)), 1) if recent else None, "model": str(out)}
