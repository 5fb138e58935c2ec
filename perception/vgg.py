"""Liu and Wang's VGG-16 regressor (Deeper Direct Perception in Autonomous Driving): torchvision's VGG-16 trunk,
fully connected layers replaced by 4096-256-N.

By default the thirteen convolutional layers are frozen and only the new head learns (Liu and Wang, section 6:
"fixing the pre-trained weights for all convolutional layers"); `frozen=False` fine-tunes everything (the paper's first
item of future work) and `batch_norm=True` uses vgg16_bn (its second). No dropout, no output sigmoid.
"""
from __future__ import annotations

import torch
from torch import nn
from torchvision.models.vgg import cfgs, make_layers

from perception.models import Family, ModelInput, one_camera_now, register


class VGGRegressor(nn.Module):
    def __init__(self, num_outputs: int = 13, batch_norm: bool = False, frozen: bool = True) -> None:
        super().__init__()
        self.features = make_layers(cfgs["D"], batch_norm=batch_norm)  # torchvision's VGG-16 ("D") trunk
        self.avgpool = nn.AdaptiveAvgPool2d((7, 7))  # 210x280 input ends in 6x8 cells, pooled to 7x7 as in torchvision
        self.regressor = nn.Sequential(
            nn.Linear(512 * 7 * 7, 4096),
            nn.ReLU(inplace=True),
            nn.Linear(4096, 256),
            nn.ReLU(inplace=True),
            nn.Linear(256, num_outputs),
        )
        for m in self.modules():  # torchvision's VGG initialisation
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
                if m.bias is not None:
                    nn.init.constant_(m.bias, 0)
            elif isinstance(m, nn.BatchNorm2d):
                nn.init.constant_(m.weight, 1)
                nn.init.constant_(m.bias, 0)
            elif isinstance(m, nn.Linear):
                nn.init.normal_(m.weight, 0, 0.01)
                nn.init.constant_(m.bias, 0)
        head = self.regressor[-1]
        assert isinstance(head, nn.Linear)
        nn.init.constant_(head.bias, 0.5)  # middle of the normalised range
        self.frozen = frozen
        self.features.requires_grad_(not frozen)

    def train(self, mode: bool = True) -> VGGRegressor:
        super().train(mode)
        if self.frozen:  # a frozen trunk keeps its batch-norm statistics too
            self.features.eval()
        return self

    def forward(self, x: torch.Tensor, modes: torch.Tensor | None = None) -> torch.Tensor:
        x = self.features(x)
        x = self.avgpool(x)
        x = torch.flatten(x, 1)
        return self.regressor(x)


def vgg16(num_outputs: int = 13, batch_norm: bool = False, frozen: bool = True) -> VGGRegressor:
    """VGG-16 (or VGG-16-BN) for `num_outputs` indicators; load ImageNet trunk weights with models.load_trunk."""
    return VGGRegressor(num_outputs, batch_norm=batch_norm, frozen=frozen)


def _build(inp: ModelInput, outputs: int, options: dict) -> VGGRegressor:
    return VGGRegressor(outputs, batch_norm=bool(options.get("batch_norm", False)),
                        frozen=bool(options.get("frozen", True)))


def _describe(spec: dict) -> str:
    o = spec["options"]
    bits = ["conv frozen" if o.get("frozen", True) else "all layers trained",
            "ImageNet init" if o.get("weights") else "random init"]
    return ("VGG-16-BN" if o.get("batch_norm") else "VGG-16") + f" ({', '.join(bits)})"


register(Family("vgg16", "VGG-16", _build, one_camera_now, trainer="sgd",
                defaults={"iterations": 15_000, "batch_size": 10, "lr": 1e-4},   # Liu and Wang, section 6.3
                describe=_describe, settings=("unfreeze", "batch_norm")))
