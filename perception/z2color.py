"""Z2Color, the network of Chowdhuri, Pankaj and Zipser's MultiNet (2017), with modal insertion.

Input: a data moment of 12 x 94 x 168 (two instants x left/right cameras x RGB, pixels x / 255 - 0.5; cameras that
render at twice that size are averaged 2x2 on the way in). Then

    conv1 12 -> 96, 11x11 stride 3 -> ReLU -> max-pool 3/2 -> batch-norm          96 x 13 x 26
    modal insertion: the behavioural mode as a binary tensor 3 x 13 x 26 (all ones in the active mode's plane),
    concatenated                                                                   99 x 13 x 26
    conv2 99 -> 256, 3x3 stride 2 -> ReLU -> max-pool 3/2 -> batch-norm           256 x 2 x 5
    fc1 2560 -> 512 -> ReLU, fc2 512 -> 20                                         10 steering, 10 motor

The MTL baseline of the paper is the same network without the modal input (conv2 takes 96 channels), trained on
one mode's data (option modal=False). The mode enters after conv1 so that the first layer learns image features
common to every behaviour.
"""
from __future__ import annotations

import torch
from torch import nn

from core.declaration import WorldDeclaration
from perception.models import Family, ModelInput, register

INPUT_SIZE = (94, 168)     # (rows, columns) the network reads
ASPECT_TOLERANCE = 0.05


class Z2Color(nn.Module):
    def __init__(self, channels: int = 12, outputs: int = 20, modes: int = 3, modal: bool = True):
        super().__init__()
        self.modes = modes if modal else 0
        self.conv1 = nn.Sequential(nn.Conv2d(channels, 96, kernel_size=11, stride=3), nn.ReLU(inplace=True),
                                   nn.MaxPool2d(3, 2), nn.BatchNorm2d(96))
        self.conv2 = nn.Sequential(nn.Conv2d(96 + self.modes, 256, kernel_size=3, stride=2), nn.ReLU(inplace=True),
                                   nn.MaxPool2d(3, 2), nn.BatchNorm2d(256))
        self.fc = nn.Sequential(nn.Flatten(), nn.Linear(256 * 2 * 5, 512), nn.ReLU(inplace=True),
                                nn.Linear(512, outputs))

    def mode_planes(self, modes: torch.Tensor, height: int, width: int) -> torch.Tensor:
        """The behavioural mode as a binary tensor (B, modes, height, width): ones in the active mode's plane
        (a mode index of -1, no mode, gives all zeros)."""
        onehot = torch.zeros(modes.shape[0], self.modes, device=modes.device)
        valid = (modes >= 0) & (modes < self.modes)
        onehot[valid, modes[valid]] = 1.0
        return onehot[:, :, None, None].expand(-1, -1, height, width)

    def forward(self, x: torch.Tensor, modes: torch.Tensor | None = None) -> torch.Tensor:
        x = self.conv1(x)
        if self.modes:
            if modes is None:
                modes = torch.full((x.shape[0],), -1, dtype=torch.int64, device=x.device)
            x = torch.cat([x, self.mode_planes(modes, x.shape[2], x.shape[3])], dim=1)
        return self.fc(self.conv2(x))


def _fits(decl: WorldDeclaration) -> str | None:
    target = INPUT_SIZE[1] / INPUT_SIZE[0]
    for c in decl.cameras:
        if c.height < INPUT_SIZE[0] or c.width < INPUT_SIZE[1] or abs(c.width / c.height / target - 1) > \
                ASPECT_TOLERANCE:
            return f"it reads {INPUT_SIZE[1]}x{INPUT_SIZE[0]} images; camera {c.name} is {c.width}x{c.height}"
    return None


def _build(inp: ModelInput, outputs: int, options: dict) -> Z2Color:
    return Z2Color(inp.channels, outputs, inp.modes, modal=bool(options.get("modal", True)) and inp.modes > 0)


def _describe(spec: dict) -> str:
    o = spec["options"]
    if o.get("modal", True) and spec["input"].get("modes"):
        return "Z2Color (MultiNet)"
    return f"Z2Color (MTL, {o['mtl']})" if o.get("mtl") else "Z2Color (no modes)"


# drives_bf16: the first convolution is most of a drive's step; under bfloat16 a frame's prediction takes 5.2 ms
# against 7.5 in float32 (batch 1, one thread, AVX512-BF16), its outputs within 0.003 of float32's
register(Family("z2color", "Z2Color", _build, _fits, scaling="centre", trainer="multinet",
                size=lambda decl: INPUT_SIZE, describe=_describe, drives_bf16=True,
                defaults={"epochs": 24, "batch_size": 120, "clip": 1.0}))
