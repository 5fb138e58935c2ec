"""The optimisers both trainers build (perception/train_sgd.py for the highway regressors, perception/multinet.py for
Z2Color), by name, with PyTorch's fastest implementation that computes the same update.

Fused kernels (one pass over each parameter for the whole update) where PyTorch has them (Adam, SGD): the default
for-loop implementation makes several passes, each allocating a temporary the size of the parameter, which on a CPU
is memory-bound. For AlexNet's 58 M parameters that was half a second of Adam per iteration on one core, a third of
the training step; fused, 0.04 s. Adadelta has no fused kernel: its multi-tensor ("foreach") one.
"""
from __future__ import annotations

import torch

OPTIMIZERS = ("sgd", "adam", "adadelta")


def make_optimizer(name: str, params, lr: float, momentum: float = 0.9,
                   weight_decay: float = 0.0) -> torch.optim.Optimizer:
    """The optimiser `name` over `params` (ValueError for an unknown name)."""
    params = list(params)
    fused = all(p.device.type in ("cpu", "cuda") for p in params)   # the devices with fused kernels
    if name == "sgd":
        return torch.optim.SGD(params, lr=lr, momentum=momentum, weight_decay=weight_decay, fused=fused or None)
    if name == "adam":
        return torch.optim.Adam(params, lr=lr, weight_decay=weight_decay, fused=fused or None)
    if name == "adadelta":
        return torch.optim.Adadelta(params, lr=lr, weight_decay=weight_decay, foreach=True)
    raise ValueError(f"unknown optimizer '{name}' ({', '.join(OPTIMIZERS)})")
