"""What every trainer shares (the SGD trainer of perception/train_sgd.py, GIST's closed-form fit of
perception/gist_fit.py, Z2Color's of perception/multinet.py): the run's configuration (TrainConfig, whose settings
perception/train_config.py holds), its targets, the device, the data and its validation frames, the Euclidean loss
and the per-output MAE.

Liu and Wang's training (Deeper Direct Perception, sections 6.1 and 6.3): the Euclidean loss
L = 1/(2m) sum ||y_hat - y||^2 on targets normalised to about [0.1, 0.9]; no dropout, no output sigmoid; the
families' numbers are theirs (perception/alexnet.py, vgg.py).
"""
from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import numpy as np
import torch

from core.declaration import DeclarationError, Moment, WorldDeclaration
from perception.datasets import FrameDataset
from perception.models import Regressor, family, fitting
from perception.shards import Dataset
from perception.train_config import TrainConfig


class TrainingError(ValueError):
    """Training that cannot go on: the loss diverged, or the run's settings contradict its checkpoint."""


def run_targets(cfg: TrainConfig, decl: WorldDeclaration) -> tuple[str, ...]:
    """The targets of a run for a dataset of world `decl`."""
    return resolve_targets(decl, cfg.targets, extra=tuple(
        n for n, on in (("fast", cfg.fast), ("lanes_left", cfg.lanes_left)) if on), label_set=cfg.labels)


def resolve_targets(decl: WorldDeclaration, text: str | None, extra=(), label_set: str | None = None) \
        -> tuple[str, ...]:
    """The targets `text` (TrainConfig.targets) names: a label set of the world ("extended"), labels in place of the
    default ("a,b"), labels added to it ("+a,+b"), or a label set and additions ("extended,+a"); `extra` adds too.
    The default is the world's targets, or the label set `label_set` (TrainConfig.labels)."""
    items = [t.strip() for t in (text or "").split(",") if t.strip()]
    names = [t for t in items if not t.startswith("+")]
    adds = [t[1:] for t in items if t.startswith("+")]
    sets = [n for n, _ in decl.label_sets]
    if len(names) == 1 and names[0] in sets and names[0] not in decl.label_names:
        if label_set not in (None, names[0]):
            raise TrainingError(f"--targets names the label set {names[0]} and labels the set {label_set}: give one")
        label_set, names = names[0], []
    if names and adds:
        raise TrainingError("--targets takes a label set or names (in place of the default targets), and +names "
                            "(added to them); not names and +names")
    if names and label_set is not None:
        raise TrainingError(f"labels names the targets (the set {label_set}); --targets may only add to them (+name)")
    try:
        default = list(decl.targets if label_set is None else decl.label_set(label_set))
    except DeclarationError as e:
        raise TrainingError(str(e)) from None
    chosen = names or default + adds
    chosen += [n for n in extra if n not in chosen]
    unknown = [n for n in chosen if n not in decl.label_names]
    if unknown:
        raise TrainingError(f"the {decl.name} world has no label {', '.join(unknown)} (labels: "
                            f"{', '.join(decl.label_names)}" + (f"; label sets: {', '.join(sets)})" if sets else ")"))
    return tuple(dict.fromkeys(chosen))


def config_from(**kwargs) -> TrainConfig:
    """A TrainConfig from keyword arguments, ignoring those that are not its fields (a caller's other options)."""
    names = {f.name for f in fields(TrainConfig)}
    return TrainConfig(**{k: v for k, v in kwargs.items() if k in names})


def euclidean_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Caffe's EuclideanLoss: 1/(2m) sum_i ||y_hat_i - y_i||^2."""
    return ((pred.float() - target.float()) ** 2).sum(1).mean() / 2


def absolute_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """The L1 counterpart: 1/m sum_i ||y_hat_i - y_i||_1. Why it exists: under the Euclidean loss an output's pull
    on the shared trunk grows with its error, so the gaps' misses of tens of metres drown the angle's hundredths of
    a radian; under L1 every output pulls alike, and the loss is the mean absolute error the reports measure."""
    return (pred.float() - target.float()).abs().sum(1).mean()


# the setting `loss` (its choices, train_config.LOSS_NAMES, are these names): the Euclidean loss is the papers'
# (Liu and Wang; Chen et al.) and the default of every family but the MobileNet, which trains with L1
# (perception/mobilenet.py).
LOSSES = {"euclidean": euclidean_loss, "l1": absolute_loss}


def resolve_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    device = torch.device(name)
    if device.type == "cuda" and not torch.cuda.is_available():
        raise TrainingError(f"--device {name}: no CUDA device is available here")
    return device



def open_data(cfg: TrainConfig) -> tuple[Dataset, WorldDeclaration, tuple[str, ...]]:
    """The dataset, its world and this run's targets; refuses a family that does not fit the world."""
    data = Dataset(Path(cfg.data))
    decl = data.declaration
    fam = family(cfg.model)
    why = fam.fits(decl)
    if why is not None:
        raise TrainingError(f"--model {cfg.model} does not fit the {decl.name} world of {cfg.data}: {why} "
                            f"(models for it: {', '.join(fitting(decl)) or 'none'})")
    return data, decl, run_targets(cfg, decl)


def data_summary(data: Dataset) -> dict:
    """What a checkpoint records of its training data: where, how much per split, and the manifest's fields."""
    return {"root": str(data.root.resolve()),
            "frames": {s: data.frames(s) for s in ("train", "val", "test")},
            "episodes": len(data.shards),
            "manifest": {k: v for k, v in data.manifest.items() if k != "shards"}}


def spread(n: int, k: int) -> list[int]:
    """k indices evenly spread over range(n)."""
    return sorted(set(np.linspace(0, n - 1, num=min(n, k)).round().astype(int).tolist())) if n else []


def history_moment(decl: WorldDeclaration, history: int) -> Moment | None:
    """The data moment of a model reading `history` earlier frames beside the current one (None: the world's)."""
    if not history:
        return None
    return Moment(instants=tuple(range(-history, 1)), horizon=decl.moment.horizon)


def load_frames(root, split: str, labels, limit: int, normalised: bool = True, moment: Moment | None = None):
    """Up to `limit` samples of a split, evenly spread over it, as (uint8 images, modes, targets) tensors."""
    ds = FrameDataset(root, split, labels, normalised=normalised, moment=moment)
    items = [ds[i] for i in spread(len(ds), limit)]
    return tuple(torch.stack([item[k] for item in items]) for k in range(3))


def input_statistics(root, labels, frames: int = 512,
                     moment: Moment | None = None) -> tuple[list[float], list[float]]:
    """Per-channel mean and standard deviation of training samples in [0, 1] (Liu and Wang's mean file)."""
    images, _, _ = load_frames(root, "train", labels, frames, moment=moment)
    x = images.float().div_(255).transpose(0, 1).reshape(images.shape[1], -1)
    return x.mean(1).tolist(), x.std(1).clamp_min(1e-3).tolist()


@torch.no_grad()
def predict_all(model: Regressor, images: torch.Tensor, modes: torch.Tensor, device, batch: int = 50) -> torch.Tensor:
    """The model's outputs for every sample, in eval mode, batch by batch (float32 on the CPU)."""
    was_training = model.training
    model.eval()
    preds = torch.cat([model(images[i:i + batch].to(device), modes[i:i + batch].to(device)).float().cpu()
                       for i in range(0, len(images), batch)])
    model.train(was_training)
    return preds


def validate(model: Regressor, images: torch.Tensor, modes: torch.Tensor, targets: torch.Tensor, device,
             batch: int = 50, loss: str = "euclidean") -> dict:
    """The training loss `loss` (normalised; so the curves compare like with like) and mean absolute error per
    output (in the labels' units)."""
    preds = predict_all(model, images, modes, device, batch)
    mae = np.abs(model.denormalise(preds) - model.denormalise(targets)).mean(0)
    return {"val_loss": float(LOSSES[loss](preds, targets)),
            "val_mae": {n: float(v) for n, v in zip(model.outputs, mae)}}
