"""An exponential moving average of a model's weights and batch-norm statistics (`train --set ema=DECAY`).

Why: with Adam at a constant learning rate a small network's weights keep jittering, and so does what it reads
from a frame: the demo's MobileNet read the angle 0.039, 0.046 and 0.047 rad wrong (validation MAE) at 1,500,
1,800 and 2,100 iterations. The average of the recent weights sits in the middle of that jitter; it read 0.036,
0.036 and 0.035 at the same iterations (docs/explanation/learned-driving.md, "The MobileNet family"; the
measurements: docs/log/2026-11-24.md). After each step

    averaged = decay * averaged + (1 - decay) * weights

over every parameter and buffer (the batch-norm running statistics too, so the averaged model is consistent
without a pass over the data), starting from a copy of the weights. A decay of 0.995 averages over about the
last 200 steps. The run validates and saves the averaged model (what `drive`, `evaluate` and `--init` read) and
keeps the weights it trains in the checkpoint beside it, so an interrupted run continues exactly.
"""
from __future__ import annotations

import torch
from torch import nn
from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn


class WeightAverage:
    """The moving average of `model`'s weights: update() after each optimiser step, `module` to use it."""

    def __init__(self, model: nn.Module, decay: float) -> None:
        if not 0.0 < decay < 1.0:
            raise ValueError(f"a moving-average decay lies strictly between 0 and 1, not {decay}")
        self.decay = decay
        self._avg = AveragedModel(model, multi_avg_fn=get_ema_multi_avg_fn(decay), use_buffers=True)

    @property
    def module(self) -> nn.Module:
        """The averaged model (the same class as the trained one)."""
        return self._avg.module

    @property
    def steps(self) -> int:
        return int(self._avg.n_averaged.item())

    @torch.no_grad()
    def update(self, model: nn.Module) -> None:
        self._avg.update_parameters(model)

    def load(self, state_dict: dict, steps: int) -> None:
        """Continue an average a checkpoint saved: its averaged weights and how many steps it has seen."""
        self.module.load_state_dict(state_dict)
        self._avg.n_averaged.fill_(steps)
