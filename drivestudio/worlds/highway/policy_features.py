"""The input layer of the reinforcement-learning policies: affordances scaled from their Box bounds to [-1, 1].

The gaps run to 75 m, the angle to pi: fed raw, the wide ones saturate the policy's tanh units. The scaling comes
from the observation space's own bounds (sim/highway/gym_env.py BOUNDS), as fixed buffers of the network, so a saved
model reads the environment's exact affordances with nothing beside it (no running statistics to save and load).
Imported only where Stable-Baselines3 is installed (the optional `rl` extra).
"""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor


class ScaledBox(BaseFeaturesExtractor):
    """A Box observation with finite bounds, mapped linearly onto [-1, 1] and flattened."""

    centre: torch.Tensor   # buffers: saved with the weights, moved with the module
    radius: torch.Tensor

    def __init__(self, observation_space: gym.spaces.Box):
        if not (np.isfinite(observation_space.low).all() and np.isfinite(observation_space.high).all()):
            raise ValueError("ScaledBox needs an observation space with finite bounds")
        super().__init__(observation_space, features_dim=int(np.prod(observation_space.shape)))
        low = torch.as_tensor(observation_space.low, dtype=torch.float32)
        high = torch.as_tensor(observation_space.high, dtype=torch.float32)
        self.register_buffer("centre", (low + high) / 2)
        self.register_buffer("radius", torch.clamp((high - low) / 2, min=1e-6))

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return ((observations - self.centre) / self.radius).flatten(1)
