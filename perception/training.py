"""What every trainer shares (the SGD trainer of perception/train_sgd.py, GIST's closed-form fit of
perception/gist_fit.py, Z2Color's of perception/multinet.py): the run's configuration, its targets, the device,
the data and its validation frames, the Euclidean loss and the per-output MAE.

The defaults are Liu and Wang's (Deeper Direct Perception, sections 6.1 and 6.3): SGD with momentum 0.9,
learning rate x0.9 every 1000 iterations, AlexNet from scratch at lr 1e-2 with batches of 15 for 10,000 iterations,
VGG-16 (conv frozen) at lr 1e-4 with batches of 10 for 15,000 iterations, Euclidean loss
L = 1/(2m) sum ||y_hat - y||^2 on targets normalised to about [0.1, 0.9]; no dropout, no output sigmoid.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import torch

from core.declaration import DeclarationError, Moment, WorldDeclaration
from perception.datasets import FrameDataset
from perception.models import Regressor, family, fitting
from perception.shards import Dataset


class TrainingError(ValueError):
    """Training that cannot go on: the loss diverged, or the run's settings contradict its checkpoint."""


@dataclass
class TrainConfig:
    data: str = "out/dataset"
    model: str = "alexnet"            # a family of perception/models.py that fits the dataset's world
    out: str = "runs/alexnet.pt"
    targets: str | None = None        # comma-separated labels (default: the world's); "+name" adds to the default
    labels: str | None = None         # a named label set of the world (highway: paper, extended) as the default
    iterations: int | None = None     # None: the paper's for the model (or from `epochs`)
    epochs: float | None = None       # alternative to iterations: passes over the training split
    batch_size: int | None = None     # None: the paper's (15 AlexNet, 10 VGG-16)
    lr: float | None = None           # None: the paper's (1e-2 AlexNet, 1e-4 VGG-16)
    lr_step: int = 1000               # iterations between learning-rate decays
    lr_gamma: float = 0.9
    optimizer: str | None = None      # sgd (Liu and Wang's, momentum 0.9) | adam | adadelta; None: the family's
    loss: str | None = None           # a name of LOSSES; None: the checkpoint's (continued, --init), else the family's
    ema: float | None = None          # decay of the weights' moving average (0: none); None: the family's
    momentum: float = 0.9
    weight_decay: float = 0.0
    device: str = "auto"              # auto | cpu | cuda | cuda:N
    amp: bool = True                  # mixed precision on CUDA (bf16 where supported, else fp16)
    workers: int = 1                  # DataLoader processes decoding frames
    shuffle_buffer: int = 16384       # frames mixed across episodes before batching
    val_every: int = 500              # iterations between validations (and checkpoints)
    checkpoint_every: float = 300.0   # [s] also save at least this often (a kill loses at most this much)
    val_frames: int = 1000            # at most this many validation frames, evenly spread over the split
    log_every: int = 10               # iterations per row of the loss curve
    unfreeze: bool = False            # VGG-16: train the convolutional layers too
    batch_norm: bool = False          # VGG-16: vgg16_bn
    weights: str | None = None        # torchvision ImageNet state dict for the trunk (never downloaded)
    fast: bool = False                # highway: predict `fast` too (= targets "+fast")
    lanes_left: bool = False          # highway: predict lanes_left too (Liu and Wang's proposed fix)
    regressor: str = "ridge"          # GIST: ridge | rbf
    modes: str | None = None          # Z2Color: behavioural modes to train on (comma-separated; None: all)
    mtl: str | None = None            # Z2Color: the MTL baseline on this one mode (no modal input)
    trials: int = 1                   # Z2Color: repeats with fresh seeds
    mode_moments: int | None = None   # Z2Color: at most this many moments of each mode per epoch (None: all)
    steer_share: float = 0.0          # Z2Color: share of each mode's draws from its steering moments (multinet.py)
    init: str | None = None           # start from this checkpoint's weights (fine-tuning, aggregation rounds)
    history: int = 0                  # earlier frames read beside the current one (a temporal family)
    cache: bool = True                # decode the training frames once into the dataset's frame cache
    channels_last: bool = True        # CPU: channels-last weights and inputs (oneDNN's faster convolutions)
    emphasis: int = 1                 # an epoch shows the world's decisive steps this many times (datasets.py)
    seed: int = 0

    def labels_for(self, decl: WorldDeclaration) -> tuple[str, ...]:
        """The targets of this run for a dataset of world `decl`."""
        return resolve_targets(decl, self.targets, extra=tuple(
            n for n, on in (("fast", self.fast), ("lanes_left", self.lanes_left)) if on), label_set=self.labels)


def resolve_targets(decl: WorldDeclaration, text: str | None, extra=(), label_set: str | None = None) \
        -> tuple[str, ...]:
    """--targets: "a,b" replaces the default targets, "+a,+b" adds to them; `extra` adds too. The default is the
    world's, or its label set named by --labels."""
    items = [t.strip() for t in (text or "").split(",") if t.strip()]
    if label_set is not None:
        try:
            default = list(decl.label_set(label_set))
        except DeclarationError as e:
            raise TrainingError(f"--labels: {e}") from None
    else:
        default = list(decl.targets)
    if items and all(not t.startswith("+") for t in items):
        if label_set is not None:
            raise TrainingError("--labels names the targets; --targets may only add to them (+name)")
        names = items
    elif any(not t.startswith("+") for t in items):
        raise TrainingError("--targets takes either names (replacing the defaults) or +names (adding to them)")
    else:
        names = default + [t[1:] for t in items]
    names += [n for n in extra if n not in names]
    known = set(decl.label_names)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise TrainingError(f"the {decl.name} world has no label {', '.join(unknown)} "
                            f"(labels: {', '.join(decl.label_names)})")
    return tuple(dict.fromkeys(names))


def config_from(**kwargs) -> TrainConfig:
    """A TrainConfig from keyword arguments, ignoring those that are not its fields (e.g. argparse extras)."""
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


# `train --loss` (its choices are these names): the Euclidean loss is the papers' (Liu and Wang; Chen et al.) and the
# default of every family but the MobileNet, which trains with L1 (perception/mobilenet.py).
LOSSES = {"euclidean": euclidean_loss, "l1": absolute_loss}


def resolve_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    device = torch.device(name)
    if device.type == "cuda" and not torch.cuda.is_available():
        raise TrainingError(f"--device {name}: no CUDA device is available here")
    return device


def bf16_native(device: torch.device) -> bool:
    """Whether bfloat16 arithmetic is native on `device`: a CUDA device that supports it, or a CPU with AVX512-BF16
    or AMX. Elsewhere oneDNN emulates it: measured on an AVX2-only CPU (AMD EPYC, one thread), Z2Color trained
    at 11 moments/s under bfloat16 autocast against 75 in float32, so autocast is used only where it is native."""
    if device.type == "cuda":
        return torch.cuda.is_bf16_supported()
    if device.type != "cpu":
        return False
    checks = (getattr(torch.cpu, "_is_avx512_bf16_supported", None), getattr(torch.cpu, "_is_amx_tile_supported", None))
    return any(bool(check()) for check in checks if check is not None)


def open_data(cfg: TrainConfig) -> tuple[Dataset, WorldDeclaration, tuple[str, ...]]:
    """The dataset, its world and this run's targets; refuses a family that does not fit the world."""
    data = Dataset(Path(cfg.data))
    decl = data.declaration
    fam = family(cfg.model)
    why = fam.fits(decl)
    if why is not None:
        raise TrainingError(f"--model {cfg.model} does not fit the {decl.name} world of {cfg.data}: {why} "
                            f"(models for it: {', '.join(fitting(decl)) or 'none'})")
    return data, decl, cfg.labels_for(decl)


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
