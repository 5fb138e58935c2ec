"""DeepDriving's AlexNet regressor: five conv(-relu-pool) layers, then fully connected 4096-4096-256-N.

The convolutional trunk and pooling are torchvision's AlexNet (for 210x280 input the trunk ends in 5x7 cells,
pooled to 6x6); the head replaces the 1000-way classifier. Trained from scratch as in Liu and Wang, section 6: no
dropout (it made the regression loss unstable) and no output sigmoid (it slowed convergence, section 6.3).
"""
from __future__ import annotations

import torch
from torch import nn
from torchvision.models import alexnet as tv_alexnet

from perception.models import Family, ModelInput, one_camera_now, register


class AlexNetRegressor(nn.Module):
    def __init__(self, num_outputs: int = 13) -> None:
        super().__init__()
        with torch.device("meta"):  # torchvision's layers without allocating its 1000-way classifier
            trunk = tv_alexnet(weights=None)
        self.features = trunk.features.to_empty(device="cpu")
        for m in self.features:
            if isinstance(m, nn.Conv2d):
                m.reset_parameters()
        self.avgpool = trunk.avgpool
        self.regressor = nn.Sequential(
            nn.Linear(256 * 6 * 6, 4096),
            nn.ReLU(inplace=True),
            nn.Linear(4096, 4096),
            nn.ReLU(inplace=True),
            nn.Linear(4096, 256),
            nn.ReLU(inplace=True),
            nn.Linear(256, num_outputs),
        )
        # Start the outputs at the middle of the normalised range [0.1, 0.9] rather than at 0.
        head = self.regressor[-1]
        assert isinstance(head, nn.Linear)
        nn.init.constant_(head.bias, 0.5)

    def forward(self, x: torch.Tensor, modes: torch.Tensor | None = None) -> torch.Tensor:
        x = self.features(x)
        x = self.avgpool(x)
        x = torch.flatten(x, 1)
        return self.regressor(x)


def alexnet(num_outputs: int = 13) -> AlexNetRegressor:
    """AlexNet for `num_outputs` indicators, randomly initialised (DeepDriving trains it from scratch)."""
    return AlexNetRegressor(num_outputs)


def _build(inp: ModelInput, outputs: int, options: dict) -> AlexNetRegressor:
    return AlexNetRegressor(outputs)


register(Family(
    "alexnet", "AlexNet", _build, one_camera_now, trainer="sgd",
    defaults={"iterations": 10_000, "batch_size": 15, "lr": 1e-2},   # Liu and Wang, section 6.1
    describe=lambda spec: "AlexNet" + (" (ImageNet init)" if spec["options"].get("weights") else "")))
