"""A trained model as a driver's perception: the images of one sample in, the model's outputs out.

    predict = load_predictor("runs/alexnet.pt")
    values = predict([frame])               # np.float64 (len(predict.outputs),), in the labels' units
    predict.named([frame])                  # {output name: value}

A sample's images are the world's cameras at the model's instants, oldest first (the highway: [front frame];
MultiNet: [left t-1, right t-1, left t, right t]); perception/history.py keeps the earlier steps' images for a
driver that sees one step at a time. Frames of another size than the model's input are resampled inside the
model, as in training.
"""
from __future__ import annotations

from contextlib import nullcontext

import numpy as np
import torch

from perception.models import describe, family, frame_inset, load_model
from perception.precision import bf16_native


class Predictor:
    """amp: compute under bfloat16 autocast (None: where the family drives so and bfloat16 is native here)."""

    def __init__(self, model, spec: dict, device: str | torch.device = "cpu", amp: bool | None = None):
        self.model, self.spec, self.device = model, spec, torch.device(device)
        self.amp = (family(spec["name"]).drives_bf16 if amp is None else amp) and bf16_native(self.device)
        if self.device.type == "cpu":   # oneDNN's convolutions are faster on channels-last weights (Z2Color: -15 %)
            self.model = model.to(memory_format=torch.channels_last)
        self.name: str = spec["name"]
        self.world: str = spec["world"]
        self.description: str = describe(spec)
        self.labels: tuple[str, ...] = tuple(spec["labels"])
        self.outputs: tuple[str, ...] = tuple(spec["outputs"])
        self.instants: tuple[int, ...] = tuple(spec["input"]["instants"])
        self.cameras: tuple[str, ...] = tuple(spec["input"]["cameras"])
        self.inset: str = frame_inset(spec)    # what its frames held besides the scene: a world must render the same
        self.modes: tuple[str, ...] = tuple(spec["input"].get("modes", ()))
        self.channels = int(spec["input"]["channels"])

    def _batch(self, samples) -> torch.Tensor:
        samples = [[images] if isinstance(images, np.ndarray) else list(images) for images in samples]
        for images in samples:
            for f in images:
                if f.ndim != 3 or f.dtype != np.uint8:
                    raise ValueError(f"expected (h, w, c) uint8 images, got {f.dtype} {f.shape}")
            channels = sum(f.shape[2] for f in images)
            if channels != self.channels or any(f.shape[:2] != images[0].shape[:2] for f in images):
                raise ValueError(f"{self.description} reads {self.channels} channels per sample "
                                 f"({len(self.instants)} instant(s) x cameras {', '.join(self.cameras)}) of one "
                                 f"size, got {' + '.join('x'.join(map(str, f.shape)) for f in images)}")
        h, w = samples[0][0].shape[:2]
        if any(images[0].shape[:2] != (h, w) for images in samples):
            raise ValueError("the samples of a batch must have images of one size")
        # each (h, w, c) image copied once, straight into its channels of the (B, C, h, w) batch: a quarter of the
        # time of concatenating along the channel axis in NumPy and transposing after (MultiNet's batch-1 latency)
        out = torch.empty((len(samples), self.channels, h, w), dtype=torch.uint8)
        for b, images in enumerate(samples):
            c = 0
            for f in images:
                out[b, c:c + f.shape[2]].copy_(torch.from_numpy(f).permute(2, 0, 1))
                c += f.shape[2]
        return out.to(self.device)

    def _modes(self, modes, n: int) -> torch.Tensor:
        if modes is None:
            return torch.full((n,), -1, dtype=torch.int64, device=self.device)
        values = [self.modes.index(m) if isinstance(m, str) else int(m) for m in
                  (modes if isinstance(modes, (list, tuple, np.ndarray)) else [modes] * n)]
        return torch.tensor(values, dtype=torch.int64, device=self.device)

    @torch.inference_mode()
    def batch(self, samples, modes=None) -> np.ndarray:
        """Every output for a batch of samples, denormalised: (B, len(outputs)) float64."""
        x = self._batch(samples)
        with torch.autocast(self.device.type, dtype=torch.bfloat16) if self.amp else nullcontext():
            outputs = self.model(x, self._modes(modes, len(x)))
        return self.model.denormalise(outputs)

    def __call__(self, images, mode=None) -> np.ndarray:
        """The outputs for one sample (its images, or the single image of a one-camera, one-instant model)."""
        return self.batch([images], None if mode is None else [mode])[0]

    def named(self, images, mode=None) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.outputs, self(images, mode))}

    def __repr__(self) -> str:
        return f"Predictor({self.description}, {len(self.outputs)} outputs, {self.device})"


def load_predictor(path, device: str = "cpu", world: str | None = None, amp: bool | None = None) -> Predictor:
    """The predictor of a checkpoint written by `drivestudio train` (loaded without running pickled code);
    `world`, when given, must be the world it was trained for; `amp` as Predictor's."""
    model, ckpt = load_model(path, device=device, world=world)
    return Predictor(model, ckpt["spec"], device, amp)
