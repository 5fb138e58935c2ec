"""A modern efficient regressor beside AlexNet and VGG-16: torchvision's MobileNetV2 building blocks (inverted
residuals of depthwise-separable convolutions, batch-norm throughout), sized for DeepDriving's 280x210 frames.

Why: on a CPU AlexNet trains at about 20 samples/s (58 M parameters, most in its fully connected layers), so the
closed-loop experiments (data aggregation rounds, the demo) cannot afford it. This trunk has about 0.1 M
convolution weights and reads the frame at half resolution (140x105, each pixel the mean of a 2x2 block: the
family's input size), where a car 60 m ahead is still several pixels wide. Unlike classification trunks it keeps
the spatial layout to the end: the last 7x9 map (32 channels) is flattened into the head, since the indicators are
positions and distances in the image, not a class.

    stem    3x3 conv, stride 2, 16 channels                         -> 53 x 70
    blocks  inverted residuals (expansion 4): 24 (stride 2), 24, 40 (stride 2), 40, 80 (stride 2), 80, 96
                                                                    -> 7 x 9
    reduce  1x1 conv to 32 channels                                 -> 32 x 7 x 9 = 2016
    head    fully connected 2016-256-N

The input may hold several instants (the current frame and the previous one or two, `train --set history=K`, as
Conditional Affordance Learning feeds its temporal heads): 3 channels per instant. No ImageNet weights exist for
this trunk here; it trains from scratch, the modern way rather than the papers': Adam, batches of 32, the L1 loss
(the Euclidean one let the gaps' large misses drown the angle) and a moving average of the weights as the model
(perception/weight_average.py). On validation frames made like the demo's, these two took the angle's error from
0.048 to 0.036 rad at 1,500 iterations and the markings' down by about a third (docs/aggregation.md).
"""
from __future__ import annotations

import torch
from torch import nn
from torchvision.models.mobilenetv2 import InvertedResidual
from torchvision.ops.misc import Conv2dNormActivation

from perception.models import Family, ModelInput, one_camera_now, register

INPUT_SIZE = (105, 140)    # (rows, columns): the 280x210 frame averaged 2x2
BLOCKS = ((24, 2), (24, 1), (40, 2), (40, 1), (80, 2), (80, 1), (96, 1))   # (channels, stride), expansion 4
REDUCED = 32


class MobileNetRegressor(nn.Module):
    def __init__(self, channels: int, height: int, width: int, outputs: int) -> None:
        super().__init__()
        layers: list[nn.Module] = [Conv2dNormActivation(channels, 16, 3, stride=2)]
        c = 16
        for out, stride in BLOCKS:
            layers.append(InvertedResidual(c, out, stride, expand_ratio=4))
            c = out
        layers.append(Conv2dNormActivation(c, REDUCED, 1))
        self.features = nn.Sequential(*layers)
        with torch.no_grad():
            cells = self.features(torch.zeros(1, channels, height, width)).numel()
        last = nn.Linear(256, outputs)
        # Start the outputs at the middle of the normalised range [0.1, 0.9] rather than at 0.
        nn.init.constant_(last.bias, 0.5)
        self.regressor = nn.Sequential(nn.Flatten(), nn.Linear(cells, 256), nn.ReLU(inplace=True), last)

    def forward(self, x: torch.Tensor, modes: torch.Tensor | None = None) -> torch.Tensor:
        return self.regressor(self.features(x))


def _build(inp: ModelInput, outputs: int, options: dict) -> MobileNetRegressor:
    return MobileNetRegressor(inp.channels, inp.height, inp.width, outputs)


def _size(decl) -> tuple[int, int]:
    cam = decl.cameras[0]
    return (cam.height // 2, cam.width // 2) if (cam.height, cam.width) != (210, 280) else INPUT_SIZE


def _describe(spec: dict) -> str:
    instants = len(spec["input"].get("instants", [0]))
    return "MobileNet" + (f" ({instants} frames)" if instants > 1 else "")


register(Family(
    "mobilenet", "MobileNet", _build, one_camera_now, trainer="sgd", size=_size, temporal=True,
    defaults={"iterations": 20_000, "batch_size": 32, "lr": 1e-3, "optimizer": "adam", "loss": "l1", "ema": 0.995},
    describe=_describe))
