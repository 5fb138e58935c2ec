"""A trained model as the closed loop's perception: one 280x210 RGB frame in, the 14 indicators out.

    predict = load_predictor("runs/alexnet.pt")
    indicators = predict(frame)      # np.float64 (14,), shm_bridge.vocabulary.INDICATORS order, denormalised

drivestudio/loop.py's Driver(perception=predict) calls it once per 10 Hz frame. An indicator the model does not
predict is 0.0: for a 13-output model that is `fast` = 0, "not on a long straight", which makes the Chen
controller keep to its slower curve speed. A `lanes_left` output is not one of the 14 and is left out here
(`predict.labels_of(frame)` returns every output of the model by name, lanes_left included).
"""
from __future__ import annotations

import cv2
import numpy as np
import torch

from shm_bridge.vocabulary import INDEX, INDICATORS

from .checkpoint import load_model
from .models import describe


class Predictor:
    def __init__(self, model, spec: dict, device: str | torch.device = "cpu"):
        self.model, self.spec, self.device = model, spec, torch.device(device)
        self.name: str = spec["name"]
        self.description: str = describe(spec)
        self.labels: tuple[str, ...] = tuple(spec["labels"])
        self.size = (int(spec["input"]["height"]), int(spec["input"]["width"]))
        self._slots = [(i, INDEX[n]) for i, n in enumerate(self.labels) if n in INDEX]

    def _batch(self, frames) -> torch.Tensor:
        out = []
        for f in frames:
            f = np.asarray(f)
            if f.ndim != 3 or f.shape[2] != 3 or f.dtype != np.uint8:
                raise ValueError(f"expected an (h, w, 3) uint8 RGB frame, got {f.dtype} {f.shape}")
            if f.shape[:2] != self.size:  # the model was trained on frames of this size
                f = cv2.resize(f, self.size[::-1], interpolation=cv2.INTER_AREA)
            out.append(torch.from_numpy(np.ascontiguousarray(f.transpose(2, 0, 1))))
        return torch.stack(out).to(self.device)

    @torch.inference_mode()
    def outputs(self, frames) -> np.ndarray:
        """Every output of the model for a batch of frames, denormalised: (B, len(labels)) float64."""
        return self.model.denormalise(self.model(self._batch(frames)))

    def predict_batch(self, frames) -> np.ndarray:
        """(B, 14) indicators in canonical order; indicators the model does not predict are 0.0."""
        values = self.outputs(frames)
        out = np.zeros((len(values), len(INDICATORS)), dtype=np.float64)
        for i, j in self._slots:
            out[:, j] = values[:, i]
        return out

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        return self.predict_batch([frame])[0]

    def labels_of(self, frame: np.ndarray) -> dict[str, float]:
        """{label: value} of every output, lanes_left included."""
        return {n: float(v) for n, v in zip(self.labels, self.outputs([frame])[0])}

    def __repr__(self) -> str:
        return f"Predictor({self.description}, {len(self.labels)} outputs, {self.device})"


def load_predictor(path, device: str = "cpu") -> Predictor:
    """The predictor of a checkpoint written by `drivestudio train` (loaded without running pickled code)."""
    model, ckpt = load_model(path, device=device)
    return Predictor(model, ckpt["spec"], device)
