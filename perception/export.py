"""Exporting a trained model to ONNX for deployment (MultiNet's point: a network small enough for the car), checked
by running the exported graph with ONNX Runtime and comparing its outputs with PyTorch's.

The exported graph takes what a driver has: `images`, uint8 (B, channels, height, width) at the model's input size
(the instants x cameras x RGB of a sample, oldest first), and `modes`, int64 (B,) (the behavioural mode index; -1
for none). It returns `outputs`, float32 (B, N), in the labels' units (denormalised): MultiNet's 10 steering then 10
motor values. Input scaling and denormalisation are inside the graph, so a deployment needs no drivestudio code.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import torch
from torch import nn

from core.files import atomic_write, temporary_for
from perception.checkpoint import CheckpointError
from perception.models import family, load_model

OPSET = 17
TOLERANCE = 1e-4   # largest |ONNX Runtime - PyTorch| accepted, in the labels' units


class ExportError(CheckpointError):
    """The exported graph does not compute what the model computes (exit status 2: nothing is written)."""


class Deployable(nn.Module):
    """A Regressor with its denormalisation: uint8 images and mode indices in, label-unit outputs out."""

    def __init__(self, model):
        super().__init__()
        self.model = model
        self.register_buffer("scale", torch.tensor(model._scale))
        self.register_buffer("offset", torch.tensor(model._offset))

    def forward(self, images: torch.Tensor, modes: torch.Tensor) -> torch.Tensor:
        out = (self.model(images, modes) - self.offset) / self.scale
        # a family without behavioural modes ignores them, and the tracer drops an unused input from the graph;
        # adding them times zero keeps the documented (images, modes) interface for every family
        return out + modes.unsqueeze(1).to(out.dtype) * 0


def example_inputs(spec: dict, batch: int = 1, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    inp = spec["input"]
    g = torch.Generator().manual_seed(seed)
    images = torch.randint(0, 256, (batch, inp["channels"], inp["height"], inp["width"]), dtype=torch.uint8,
                           generator=g)
    n_modes = len(inp.get("modes", []))
    modes = torch.randint(0, max(n_modes, 1), (batch,), generator=g) if n_modes else torch.full((batch,), -1)
    return images, modes.to(torch.int64)


def export_onnx(checkpoint, path, check_batch: int = 4, tolerance: float = TOLERANCE) -> dict:
    """Write the model of `checkpoint` as ONNX to `path`, only once ONNX Runtime's outputs on random inputs agree
    with PyTorch's within `tolerance` (a NaN difference does not): nothing is written otherwise, and a family whose
    operators ONNX cannot express is refused before anything is traced. Returns sizes, parameter count and the
    largest difference."""
    try:
        import onnxruntime as ort  # lazy: an optional extra; without it, one clear line instead of an ImportError
    except ImportError:
        raise CheckpointError("exporting needs onnx and onnxruntime: pip install 'drivestudio[export]'") from None
    model, ckpt = load_model(checkpoint)
    spec = ckpt["spec"]
    fam = family(spec["name"])
    if fam.onnx is not None:
        raise CheckpointError(f"{checkpoint} holds a {fam.title} model, which cannot be exported to ONNX: {fam.onnx}")
    net = Deployable(model).eval()
    images, modes = example_inputs(spec)
    path = Path(path)
    tmp = temporary_for(path)
    try:
        with warnings.catch_warnings():   # the tracer notes the input-size test; the graph is for that size
            warnings.simplefilter("ignore")
            torch.onnx.export(net, (images, modes), str(tmp), input_names=["images", "modes"],
                              output_names=["outputs"], opset_version=OPSET, dynamo=False,
                              dynamic_axes={"images": {0: "batch"}, "modes": {0: "batch"}, "outputs": {0: "batch"}})
        data = tmp.read_bytes()
        session = ort.InferenceSession(data, providers=["CPUExecutionProvider"])
    finally:
        tmp.unlink(missing_ok=True)
    x, m = example_inputs(spec, check_batch, seed=1)
    got = session.run(["outputs"], {"images": x.numpy(), "modes": m.numpy()})[0]
    with torch.no_grad():
        want = net(x, m).numpy()
    with np.errstate(invalid="ignore"):   # inf - inf: a NaN difference, refused below
        diff = float(np.abs(got - want).max())
    if not diff <= tolerance:   # NaN compares false: a NaN difference fails too
        raise ExportError(f"the ONNX graph of {checkpoint} differs from PyTorch by {diff:.2e} on {check_batch} random "
                          f"samples (more than {tolerance:g}); nothing written")
    atomic_write(path, data)
    params = sum(p.numel() for p in model.parameters())
    return {"onnx": str(path), "bytes": len(data), "parameters": params, "float32_mb": params * 4 / 1e6,
            "max_abs_difference": diff, "outputs": list(spec["outputs"]), "inputs": {
                "images": [None, *[spec["input"][k] for k in ("channels", "height", "width")]], "modes": [None]}}
