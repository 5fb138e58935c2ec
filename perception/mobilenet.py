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
0.048 to 0.036 rad at 1,500 iterations and the markings' down by about a third (docs/explanation/learned-driving.md,
"The MobileNet family"; the measurements: docs/log/2026-11-24.md).

Under a CPU's bfloat16 autocast (perception/train_sgd.py) the three strided depthwise convolutions compute in float32
(Float32Conv): oneDNN's bfloat16 gradient of their input is several times slower than float32's, enough to cancel
what bfloat16 gains in every other layer (docs/benchmarks.md, "bfloat16 training of the regressors").
"""
from __future__ import annotations

import torch
from torch import nn
from torch.nn.utils import skip_init
from torchvision.models.mobilenetv2 import InvertedResidual
from torchvision.ops.misc import Conv2dNormActivation

from perception.models import Family, ModelInput, one_camera_now, register

INPUT_SIZE = (105, 140)    # (rows, columns): the 280x210 frame averaged 2x2
BLOCKS = ((24, 2), (24, 1), (40, 2), (40, 1), (80, 2), (80, 1), (96, 1))   # (channels, stride), expansion 4
REDUCED = 32


class Float32Conv(nn.Conv2d):
    """A convolution that computes in float32 under a CPU's autocast (its input cast up, its output float32); the same
    weights and state-dict keys as the nn.Conv2d it replaces, and the same arithmetic without autocast. Why: on an
    AVX512-BF16 AMD EPYC, one thread, batch 32, the bfloat16 backward of the first strided depthwise convolution
    took 59 ms against float32's 8, which made the whole bfloat16 step barely faster than float32's; with these
    convolutions in float32 it is 1.8x faster."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.device.type == "cpu" and torch.is_autocast_enabled("cpu"):
            with torch.autocast("cpu", enabled=False):
                return super().forward(x.float())
        return super().forward(x)


def float32_conv(conv: nn.Conv2d) -> Float32Conv:
    """`conv` as a Float32Conv with its weights (built without an initialisation: the random draws of the network's
    other layers stay what they were)."""
    new = skip_init(Float32Conv, conv.in_channels, conv.out_channels, conv.kernel_size, stride=conv.stride,
                    padding=conv.padding, dilation=conv.dilation, groups=conv.groups, bias=conv.bias is not None,
                    padding_mode=conv.padding_mode)
    new.load_state_dict(conv.state_dict())
    return new


class MobileNetRegressor(nn.Module):
    def __init__(self, channels: int, height: int, width: int, outputs: int) -> None:
        super().__init__()
        layers: list[nn.Module] = [Conv2dNormActivation(channels, 16, 3, stride=2)]
        c = 16
        for out, stride in BLOCKS:
            block = InvertedResidual(c, out, stride, expand_ratio=4)
            if stride > 1:   # its depthwise convolution (expansion, depthwise, projection): see Float32Conv
                block.conv[1][0] = float32_conv(block.conv[1][0])
            layers.append(block)
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
