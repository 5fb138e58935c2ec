"""The compiled input path (perception/input_kernels.py) computes what the tensor code computes, bit for bit."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from core.worlds.highway import HIGHWAY
from core.worlds.sidewalk import SIDEWALK
from perception.datasets import _stack
from perception.input_kernels import interleave
from perception.models import Regressor, make_spec


def frames_with_every_value(shape: tuple, seed: int) -> np.ndarray:
    pixels = np.random.default_rng(seed).integers(0, 256, shape, dtype=np.uint8)
    n = min(256, pixels.size - 4)
    pixels.reshape(-1)[:n] = np.arange(n)
    pixels.reshape(-1)[-4:] = 255          # a block of 255s: the largest sums
    return pixels


@pytest.mark.parametrize("frames", [2, 3])
def test_interleave_is_concatenation_along_the_channels(frames):
    images = [frames_with_every_value((16, 20, 3), seed) for seed in range(frames)]
    for image in images:
        image.flags.writeable = False      # the frame cache's arrays are read-only
    got = interleave(images)
    assert got.shape == (16, 20, 3 * frames)
    assert np.array_equal(got, np.concatenate(images, axis=2))
    assert np.array_equal(got[2, 4, 3:6], images[1][2, 4])               # the second frame's pixel, channels 3-5
    stacked = _stack(images, channels_last=True)
    assert stacked.shape == (3 * frames, 16, 20) and torch.equal(stacked, _stack(images, channels_last=False))


def regressor(name: str, world) -> Regressor:
    """A network of `name`; MobileNet reads two frames (6 channels) standardised by uneven statistics, so that the
    channel index of the mean and the deviation matters."""
    if name != "mobilenet":
        return Regressor(make_spec(name, world)).eval()
    return Regressor(make_spec(name, world, mean=[0.3 + 0.05 * k for k in range(6)],
                               std=[0.2 + 0.03 * k for k in range(6)], instants=(-1, 0))).eval()


@pytest.mark.parametrize("factor", [1, 2, 3])
@pytest.mark.parametrize("name", ["mobilenet", "z2color"])
def test_scale_input_compiled_is_the_tensor_path_bit_for_bit(name, factor):
    """Channels-last uint8 frames take the compiled path; the same frames in NCHW memory take the tensor path
    (area mean, /255, the family's scaling); the values agree exactly, and the result stays channels-last."""
    world = HIGHWAY if name == "mobilenet" else SIDEWALK
    net = regressor(name, world)
    assert net.scaling == ("centre" if name == "z2color" else "standardise")
    h, w = net.size
    c = int(net.spec["input"]["channels"])
    pixels = frames_with_every_value((3, h * factor, w * factor, c), factor)
    fast = torch.from_numpy(pixels).permute(0, 3, 1, 2)                    # channels-last
    slow = fast.contiguous()                                                # NCHW: the tensor path
    assert net._compiled_path(fast) and not net._compiled_path(slow)
    got, want = net.scale_input(fast), net.scale_input(slow)
    assert got.shape == want.shape == (3, c, h, w) and got.dtype == torch.float32
    assert torch.equal(got, want)
    assert got.is_contiguous(memory_format=torch.channels_last)
    i, j, k = 5, 7, c - 1      # one value by hand: the block's mean, /255, then the channel's own scaling
    block = pixels[1, i * factor:(i + 1) * factor, j * factor:(j + 1) * factor, k].astype(np.float32)
    x = np.float32(block.sum()) / np.float32(factor * factor) / np.float32(255)
    if net.scaling == "centre":
        assert got[1, k, i, j].item() == np.float32(x - np.float32(0.5))
    else:
        mean, std = net.get_buffer("mean").reshape(-1)[k], net.get_buffer("std").reshape(-1)[k]
        assert got[1, k, i, j].item() == np.float32((x - mean.numpy()) / std.numpy())


def test_scale_input_takes_the_tensor_path_when_traced():
    """Tracing (ONNX export) records the tensor operations, not a call into compiled code."""
    net = regressor("mobilenet", HIGHWAY)
    h, w = net.size
    images = torch.from_numpy(frames_with_every_value((2, 2 * h, 2 * w, 6), 0)).permute(0, 3, 1, 2)
    seen = []

    def probe(x: torch.Tensor) -> torch.Tensor:
        seen.append(net._compiled_path(x))
        return x.float()

    torch.jit.trace(probe, images, check_trace=False)
    assert seen and not any(seen)
    assert net._compiled_path(images)
