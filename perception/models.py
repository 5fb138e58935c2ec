"""The model registry and the wrapper every regressor is used through.

A model is described by a `spec`, a plain JSON-able dict that a checkpoint stores beside the weights:
    name           "alexnet" | "vgg16" | "gist"
    labels         the regression targets in output order (shm_bridge.vocabulary.label_set)
    options        family options: weights ("imagenet" or None: where the trunk started) for alexnet and
                   vgg16; batch_norm, frozen for vgg16; regressor ("ridge" | "rbf") and seed for gist
    input          {"height", "width", "mean", "std"}: frames are scaled to [0, 1], then (x - mean) / std
                   per channel; mean and std are the training frames' own (seed 002 §5.1 subtracts the
                   dataset's mean) or ImageNet's when the trunk starts from ImageNet weights
    normalisation  {label: [scale, offset]}: the vocabulary's maps the targets were trained with
`Regressor(spec)` rebuilds the network from it; its forward takes uint8 frames (B, 3, H, W) RGB and returns
normalised indicators (about [0.1, 0.9]); `denormalise` maps them back to metres, radians and flags.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from shm_bridge.vocabulary import NORMALISATION, denormalise

from .alexnet import alexnet
from .checkpoint import CheckpointError
from .gist import gist
from .vgg import vgg16

MODELS = ("alexnet", "vgg16", "gist")
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)
FRAME_SIZE = (210, 280)  # (h, w) of the world's camera frames


def make_spec(name: str, labels, mean=(0.0, 0.0, 0.0), std=(1.0, 1.0, 1.0), size=FRAME_SIZE,
              **options) -> dict:
    if name not in MODELS:
        raise ValueError(f"unknown model '{name}' (choose from {', '.join(MODELS)})")
    labels = [str(n) for n in labels]
    return {"name": name, "labels": labels, "options": dict(options),
            "input": {"height": int(size[0]), "width": int(size[1]),
                      "mean": [float(v) for v in mean], "std": [float(v) for v in std]},
            "normalisation": {n: [float(v) for v in NORMALISATION[n]] for n in labels}}


def describe(spec: dict) -> str:
    """A short human name: "AlexNet", "VGG-16 (conv frozen, ImageNet)", "GIST + ridge", with extra labels."""
    o, name = spec.get("options", {}), spec["name"]
    if name == "alexnet":
        text = "AlexNet" + (" (ImageNet init)" if o.get("weights") else "")
    elif name == "vgg16":
        bits = ["conv frozen" if o.get("frozen", True) else "all layers trained"]
        bits.append("ImageNet init" if o.get("weights") else "random init")
        text = ("VGG-16-BN" if o.get("batch_norm") else "VGG-16") + f" ({', '.join(bits)})"
    else:
        text = f"GIST + {o.get('regressor', 'ridge')}"
    extra = [n for n in spec["labels"] if n in ("fast", "lanes_left")]
    return text + (f" [+{', '.join(extra)}]" if extra else "")


class Regressor(nn.Module):
    """Input handling + network. forward: uint8 frames (B, 3, H, W) RGB -> normalised indicators (B, N)."""

    def __init__(self, spec: dict) -> None:
        super().__init__()
        self.spec = spec
        self.name, self.labels = spec["name"], tuple(spec["labels"])
        o, n = spec.get("options", {}), len(self.labels)
        if self.name == "alexnet":
            self.net = alexnet(n)
        elif self.name == "vgg16":
            self.net = vgg16(n, batch_norm=bool(o.get("batch_norm", False)), frozen=bool(o.get("frozen", True)))
        elif self.name == "gist":
            self.net = gist(n, regressor=o.get("regressor", "ridge"), seed=int(o.get("seed", 0)))
        else:
            raise CheckpointError(f"unknown model '{self.name}' (choose from {', '.join(MODELS)})")
        self.register_buffer("mean", torch.tensor(spec["input"]["mean"], dtype=torch.float32).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor(spec["input"]["std"], dtype=torch.float32).view(1, 3, 1, 1))

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        x = images.float()
        if images.dtype == torch.uint8:
            x = x / 255.0
        return self.net((x - self.mean) / self.std)

    def denormalise(self, outputs) -> np.ndarray:
        """Network outputs (..., N) -> label values in metres, radians, flags and lane counts."""
        if isinstance(outputs, torch.Tensor):
            outputs = outputs.detach().float().cpu().numpy()
        return denormalise(outputs, self.labels).astype(np.float64)


def build(name: str, labels, **kwargs) -> Regressor:
    return Regressor(make_spec(name, labels, **kwargs))


def check_normalisation(spec: dict, where: str) -> None:
    """The vocabulary owns the normalisation; a model trained with other maps would be read back wrongly."""
    for n in spec["labels"]:
        if n not in NORMALISATION:
            raise CheckpointError(f"{where}: the model predicts '{n}', which the vocabulary does not know")
        if not np.allclose(spec["normalisation"].get(n, [np.nan, np.nan]), NORMALISATION[n], rtol=0, atol=1e-9):
            raise CheckpointError(f"{where} was trained with another normalisation of '{n}' than "
                                  "shm_bridge.vocabulary's; retrain it")


def load_trunk(model: Regressor, path: str) -> int:
    """Copy the convolutional trunk of a torchvision ImageNet state dict (vgg16, vgg16_bn or alexnet; e.g.
    `vgg16-397923af.pth`) into `model`. Nothing is downloaded. Returns the number of tensors copied."""
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise CheckpointError(f"no weights file at {path}") from None
    except Exception as e:  # pickled code, truncated or not a torch file at all
        raise CheckpointError(f"{path} is not a torchvision state dict ({type(e).__name__})") from None
    if isinstance(state, dict) and isinstance(state.get("state_dict"), dict):
        state = state["state_dict"]
    if not isinstance(state, dict):
        raise CheckpointError(f"{path} is not a torchvision state dict")
    want = model.net.features.state_dict()
    got = {k[len("features."):]: v for k, v in state.items() if isinstance(k, str) and k.startswith("features.")}
    kind = {"alexnet": "AlexNet", "vgg16": "VGG-16-BN" if model.spec["options"].get("batch_norm") else "VGG-16"}
    if set(got) != set(want) or any(tuple(got[k].shape) != tuple(want[k].shape) for k in want):
        raise CheckpointError(f"{path} is not a torchvision {kind.get(model.name, model.name)} ImageNet state "
                              "dict (its convolutional layers do not match)")
    model.net.features.load_state_dict(got)
    return len(got)
