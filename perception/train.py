"""Training: one readable loop (nanoGPT's train.py is the model), configured by the dataclass below, for any
model family and world (the family's trainer decides: "sgd" here, "closed-form" GIST below, "multinet" in
perception/multinet.py).

The defaults are Liu and Wang's (Deeper Direct Perception, sections 6.1 and 6.3): SGD with momentum 0.9,
learning rate x0.9 every 1000 iterations, AlexNet from scratch at lr 1e-2 with batches of 15 for 10,000 iterations,
VGG-16 (conv frozen) at lr 1e-4 with batches of 10 for 15,000 iterations, Euclidean loss
L = 1/(2m) sum ||y_hat - y||^2 on targets normalised to about [0.1, 0.9]; no dropout, no output sigmoid.

The checkpoint at `out` is written atomically at every validation, every `checkpoint_every` seconds, at the end
and on Ctrl-C or SIGTERM; running the same training again continues from it (same data order, same optimiser
state). Loss curves go beside it as `<out>.loss.csv` and `<out>.loss.png`.

Several processes (`torchrun --nproc_per_node N -m drivestudio train ...`): the SGD loop sees torchrun's RANK,
WORLD_SIZE and LOCAL_RANK, joins the process group (gloo on the CPU, nccl on CUDA, one GPU per process: cuda:
LOCAL_RANK) and trains a DistributedDataParallel copy of the model on each rank. Each rank reads a disjoint part of
the training episodes every epoch (the same shuffled order everywhere, FrameStream's rank split) with batches of
`batch_size`: the effective batch is world_size x batch_size. The ranks run the same number of iterations; the
logged loss is the mean over ranks; rank 0 alone validates and writes the checkpoint and curves (in the same format
as a single process) while the others wait. docs/scaling.md.
"""
from __future__ import annotations

import csv
import io
import math
import os
import sys
import time
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from core.declaration import DeclarationError, WorldDeclaration
from core.files import atomic_write
from core.signals import Terminated, exit_on_sigterm
from core.signals import check as check_signals
from perception.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from perception.datasets import FrameDataset, FrameStream
from perception.models import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    Regressor,
    check_spec,
    describe,
    family,
    load_trunk,
    make_spec,
)
from perception.shards import Dataset, DatasetError


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
    init: str | None = None           # Z2Color: start from this checkpoint's weights (fine-tuning, DAgger rounds)
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


def euclidean_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Caffe's EuclideanLoss: 1/(2m) sum_i ||y_hat_i - y_i||^2."""
    return ((pred.float() - target.float()) ** 2).sum(1).mean() / 2


def resolve_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    device = torch.device(name)
    if device.type == "cuda" and not torch.cuda.is_available():
        raise TrainingError(f"--device {name}: no CUDA device is available here")
    return device


# --- several processes (torchrun) ---------------------------------------------------------------------------
@dataclass
class Distributed:
    """This process's place in a torchrun run; rank 0 of a world of 1 when there is none."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0
    initialised_here: bool = False
    device: torch.device = torch.device("cpu")   # where collectives' tensors live (nccl: this rank's GPU)

    @property
    def active(self) -> bool:
        return self.world_size > 1

    @property
    def main(self) -> bool:
        return self.rank == 0

    def barrier(self) -> None:
        if self.active:
            torch.distributed.barrier()

    def mean(self, values: list[float]) -> list[float]:
        """The mean over ranks of each value (every rank calls it at the same point)."""
        if not self.active:
            return list(values)
        t = torch.tensor(values, dtype=torch.float64, device=self.device)
        torch.distributed.all_reduce(t)
        return (t / self.world_size).cpu().tolist()

    def minimum(self, value: int) -> int:
        if not self.active:
            return value
        t = torch.tensor([value], dtype=torch.int64, device=self.device)
        torch.distributed.all_reduce(t, op=torch.distributed.ReduceOp.MIN)
        return int(t.item())

    def share(self, obj):
        """Rank 0's `obj` on every rank."""
        if not self.active:
            return obj
        box = [obj]
        torch.distributed.broadcast_object_list(box, src=0)
        return box[0]

    def close(self) -> None:
        if self.initialised_here and torch.distributed.is_initialized():
            torch.distributed.destroy_process_group()


def distributed_env() -> tuple[int, int, int] | None:
    """(rank, world size, local rank) from torchrun's environment, or None for a single process."""
    try:
        world = int(os.environ.get("WORLD_SIZE", "1"))
        if world <= 1 or "RANK" not in os.environ:
            return None
        return int(os.environ["RANK"]), world, int(os.environ.get("LOCAL_RANK", "0"))
    except ValueError:
        raise TrainingError("RANK, WORLD_SIZE and LOCAL_RANK must be integers (as torchrun sets them)") from None


def join_distributed(device: torch.device) -> tuple[Distributed, torch.device]:
    """Join torchrun's process group when launched by it (gloo on the CPU, nccl on CUDA; each process on the GPU
    of its LOCAL_RANK unless a device index was given)."""
    env = distributed_env()
    if env is None:
        return Distributed(), device
    rank, world, local = env
    if device.type == "cuda" and device.index is None:
        device = torch.device("cuda", local)
    if device.type == "cuda":
        torch.cuda.set_device(device)
    here = not torch.distributed.is_initialized()
    if here:
        torch.distributed.init_process_group("nccl" if device.type == "cuda" else "gloo", rank=rank,
                                             world_size=world)
    return Distributed(rank, world, local, here, device if device.type == "cuda" else torch.device("cpu")), device


def data_summary(data: Dataset) -> dict:
    """What a checkpoint records of its training data: where, how much per split, and the manifest's fields."""
    return {"root": str(data.root.resolve()),
            "frames": {s: data.frames(s) for s in ("train", "val", "test")},
            "episodes": len(data.shards),
            "manifest": {k: v for k, v in data.manifest.items() if k != "shards"}}


def spread(n: int, k: int) -> list[int]:
    """k indices evenly spread over range(n)."""
    return sorted(set(np.linspace(0, n - 1, num=min(n, k)).round().astype(int).tolist())) if n else []


def load_frames(root, split: str, labels, limit: int, normalised: bool = True):
    """Up to `limit` samples of a split, evenly spread over it, as (uint8 images, modes, targets) tensors."""
    ds = FrameDataset(root, split, labels, normalised=normalised)
    items = [ds[i] for i in spread(len(ds), limit)]
    return tuple(torch.stack([item[k] for item in items]) for k in range(3))


def input_statistics(root, labels, frames: int = 512) -> tuple[list[float], list[float]]:
    """Per-channel mean and standard deviation of training samples in [0, 1] (Liu and Wang's mean file)."""
    images, _, _ = load_frames(root, "train", labels, frames)
    x = images.float().div_(255).transpose(0, 1).reshape(images.shape[1], -1)
    return x.mean(1).tolist(), x.std(1).clamp_min(1e-3).tolist()


# --- curves -------------------------------------------------------------------------------------------------
def curve_paths(out) -> tuple[Path, Path]:
    out = Path(out)
    return out.with_name(out.name + ".loss.csv"), out.with_name(out.name + ".loss.png")


def write_curves(out, history: list[dict], x: str = "iteration", title: str = "") -> None:
    """The loss history as CSV and as a PNG plot (log scale), both beside the checkpoint, atomically."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    csv_path, png_path = curve_paths(out)
    columns = list(dict.fromkeys(k for row in history for k in row))
    text = io.StringIO()
    w = csv.DictWriter(text, fieldnames=columns, lineterminator="\n")
    w.writeheader()
    w.writerows({k: ("" if row.get(k) is None else row[k]) for k in columns} for row in history)
    atomic_write(csv_path, text.getvalue().encode())

    fig, ax = plt.subplots(figsize=(7, 4), dpi=100)
    for key, style in (("train_loss", "-"), ("val_loss", "o-")):
        pts = [(r[x], r[key]) for r in history if r.get(key) is not None]
        if pts:
            ax.plot(*zip(*pts), style, label=key.replace("_", " "), markersize=3)
    ax.set_xlabel(x)
    ax.set_ylabel("Euclidean loss (normalised targets)")
    if x == "alpha":
        ax.set_xscale("log")
    if any(r.get("train_loss") for r in history):
        ax.set_yscale("log")
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend()
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    atomic_write(png_path, buf.getvalue())


# --- validation ---------------------------------------------------------------------------------------------
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
             batch: int = 50) -> dict:
    """Euclidean loss (normalised) and mean absolute error per output (in the labels' units)."""
    preds = predict_all(model, images, modes, device, batch)
    mae = np.abs(model.denormalise(preds) - model.denormalise(targets)).mean(0)
    return {"val_loss": float(euclidean_loss(preds, targets)),
            "val_mae": {n: float(v) for n, v in zip(model.outputs, mae)}}


# --- the loop -----------------------------------------------------------------------------------------------
def open_data(cfg: TrainConfig) -> tuple[Dataset, WorldDeclaration, tuple[str, ...]]:
    """The dataset, its world and this run's targets; refuses a family that does not fit the world."""
    data = Dataset(Path(cfg.data))
    decl = data.declaration
    fam = family(cfg.model)
    why = fam.fits(decl)
    if why is not None:
        from perception.models import fitting
        raise TrainingError(f"--model {cfg.model} does not fit the {decl.name} world of {cfg.data}: {why} "
                            f"(models for it: {', '.join(fitting(decl)) or 'none'})")
    return data, decl, cfg.labels_for(decl)


def train(cfg: TrainConfig, log=print) -> dict:
    """Train (or continue training) `cfg.model` on `cfg.data`; returns the final checkpoint's `train` record."""
    trainer = family(cfg.model).trainer
    if trainer != "sgd" and distributed_env() is not None:
        raise TrainingError(f"--model {cfg.model} trains in one process ({trainer}); torchrun runs the SGD families "
                            "(alexnet, vgg16, ...) on several")
    if trainer == "closed-form":
        return fit_gist(cfg, log)
    if trainer == "multinet":
        from perception.multinet import train_multinet
        return train_multinet(cfg, log)
    data, decl, labels = open_data(cfg)
    dist, device = join_distributed(resolve_device(cfg.device))
    try:
        return _train_sgd(cfg, data, decl, labels, device, dist, log if dist.main else (lambda *a, **k: None))
    finally:
        dist.close()


def _train_sgd(cfg: TrainConfig, data: Dataset, decl: WorldDeclaration, labels, device: torch.device,
               dist: Distributed, log) -> dict:
    paper = family(cfg.model).defaults
    torch.manual_seed(cfg.seed)
    stream = FrameStream(cfg.data, "train", labels, shuffle=True, seed=cfg.seed,
                         buffer=min(cfg.shuffle_buffer, data.frames("train")), rank=dist.rank,
                         world_size=dist.world_size)
    batch_size = cfg.batch_size or paper["batch_size"]
    if len(stream) < batch_size * dist.world_size:
        raise DatasetError(f"the training split of {cfg.data} has {len(stream)} frames, fewer than one batch "
                           f"of {batch_size}" + (f" for each of {dist.world_size} processes" if dist.active else ""))
    if dist.active and len(stream.shards) < dist.world_size:
        raise DatasetError(f"the training split of {cfg.data} has {len(stream.shards)} episodes, fewer than the "
                           f"{dist.world_size} processes that share them")
    if cfg.epochs is not None:
        iterations = max(1, math.ceil(cfg.epochs * len(stream) / (batch_size * dist.world_size)))
    else:
        iterations = cfg.iterations if cfg.iterations is not None else paper["iterations"]
    lr = cfg.lr if cfg.lr is not None else paper["lr"]
    optimizer = cfg.optimizer or paper.get("optimizer", "sgd")
    out = Path(cfg.out)

    ckpt = None
    if out.exists():
        ckpt = load_checkpoint(out, model=cfg.model, labels=labels, world=decl.name)
        check_spec(ckpt["spec"], str(out))
        if "optimizer" not in ckpt:
            raise CheckpointError(f"{out} holds no training state to continue from")
    if ckpt is not None:
        spec = ckpt["spec"]
        o = spec["options"]
        if cfg.model == "vgg16" and o.get("frozen") == cfg.unfreeze:
            raise CheckpointError(f"{out} was trained {'without' if o.get('frozen') else 'with'} --unfreeze; use "
                                  "the same options to continue it, or another --out")
        if cfg.model == "vgg16" and bool(o.get("batch_norm")) != cfg.batch_norm:
            raise CheckpointError(f"{out} was trained {'with' if o.get('batch_norm') else 'without'} --batch-norm; "
                                  "use the same options to continue it, or another --out")
        old = ckpt["train"]["config"]
        if old.get("optimizer") != optimizer:
            raise CheckpointError(f"{out} was trained with --optimizer {old.get('optimizer')}; use the same "
                                  "optimiser to continue it, or another --out")
        if old.get("lr") != lr or old.get("batch_size") != batch_size:
            log(f"note: {out} continues with its own learning-rate schedule (started at lr {old.get('lr'):g}, "
                f"batch {old.get('batch_size')}); the settings of this run are ignored")
            lr, batch_size = old.get("lr", lr), old.get("batch_size", batch_size)
    else:
        if cfg.weights:  # ImageNet weights expect ImageNet's input statistics
            mean, std, weights = IMAGENET_MEAN, IMAGENET_STD, "imagenet"
        else:
            log("computing the per-channel input mean and deviation of the training frames ...")
            mean, std = dist.share(input_statistics(cfg.data, labels) if dist.main else None)
            weights = None
        options = {"weights": weights}
        if cfg.model == "vgg16":
            options.update(frozen=not cfg.unfreeze, batch_norm=cfg.batch_norm)
        spec = make_spec(cfg.model, decl, labels, mean=mean, std=std, **options)

    model = Regressor(spec)
    if ckpt is not None:
        model.load_state_dict(ckpt["state_dict"])
    elif cfg.weights:
        n = load_trunk(model, cfg.weights)
        log(f"{cfg.model} trunk: {n} tensors of ImageNet weights from {cfg.weights}")
    elif cfg.model == "vgg16":
        log("VGG-16 trunk: no --weights given, so the convolutional layers start from RANDOM initialisation "
            "(nothing is downloaded; pass --weights vgg16-397923af.pth for the paper's ImageNet start)"
            + ("; they stay frozen, so only the head learns" if not cfg.unfreeze else ""))
    model.to(device)
    model.train()
    net = model   # what the training steps call: the model itself, or its DistributedDataParallel wrapper
    if dist.active:
        net = torch.nn.parallel.DistributedDataParallel(model, device_ids=[device.index] if device.type == "cuda"
                                                        else None)

    params = [p for p in model.parameters() if p.requires_grad]
    if optimizer == "sgd":
        opt = torch.optim.SGD(params, lr=lr, momentum=cfg.momentum, weight_decay=cfg.weight_decay)
    elif optimizer == "adam":
        opt = torch.optim.Adam(params, lr=lr, weight_decay=cfg.weight_decay)
    elif optimizer == "adadelta":
        opt = torch.optim.Adadelta(params, lr=lr, weight_decay=cfg.weight_decay)
    else:
        raise TrainingError(f"unknown optimizer '{optimizer}' (sgd, adam or adadelta)")
    sched = torch.optim.lr_scheduler.StepLR(opt, step_size=cfg.lr_step, gamma=cfg.lr_gamma)
    amp_dtype = None
    if cfg.amp and device.type == "cuda":
        amp_dtype = torch.bfloat16 if torch.cuda.is_bf16_supported() else torch.float16
    scaler = torch.amp.GradScaler("cuda", enabled=amp_dtype == torch.float16)

    state = {"iteration": 0, "epoch": 0, "step_in_epoch": 0, "history": [], "seconds": 0.0}
    if ckpt is not None:
        opt.load_state_dict(ckpt["optimizer"])
        sched.load_state_dict(ckpt["scheduler"])
        if "scaler" in ckpt and scaler.is_enabled():
            scaler.load_state_dict(ckpt["scaler"])
        if "rng" in ckpt:
            torch.set_rng_state(ckpt["rng"])
        state.update({k: ckpt["train"][k] for k in state})
        if ckpt["train"].get("world_size", 1) != dist.world_size:
            log(f"note: {out} was trained by {ckpt['train'].get('world_size', 1)} process(es), this run has "
                f"{dist.world_size}: the data order from here on differs from an uninterrupted run")
        if ckpt["data"]["frames"] != data_summary(data)["frames"]:
            log(f"note: {out} was trained on data with {ckpt['data']['frames']} frames per split; "
                f"continuing on {cfg.data} with {data_summary(data)['frames']}")
        if state["iteration"] >= iterations:
            log(f"{out} has already trained {state['iteration']} of {iterations} iterations: nothing to do "
                "(raise --iterations to train further)")
            return ckpt["train"]
        log(f"continuing {out} from iteration {state['iteration']} of {iterations}")

    if data.frames("val") and dist.main:
        val_images, val_modes, val_targets = load_frames(cfg.data, "val", labels, cfg.val_frames)
    elif data.frames("val"):
        val_images = val_modes = val_targets = None   # rank 0 validates
    else:
        val_images = val_modes = val_targets = None
        log(f"note: {cfg.data} has no validation split (episodes 8, 18, ...); training without validation")

    def save(final: bool = False) -> None:
        if not dist.main:
            return
        config = {f.name: getattr(cfg, f.name) for f in fields(cfg)}
        config.update(iterations=iterations, batch_size=batch_size, lr=lr, optimizer=optimizer)
        payload = {"spec": spec, "state_dict": model.state_dict(), "optimizer": opt.state_dict(),
                   "scheduler": sched.state_dict(), "rng": torch.get_rng_state(),
                   "train": {**state, "config": config, "device": str(device), "finished": final},
                   "data": data_summary(data)}
        if dist.active:
            payload["train"]["world_size"] = dist.world_size
        if scaler.is_enabled():
            payload["scaler"] = scaler.state_dict()
        save_checkpoint(out, payload)
        write_curves(out, state["history"], title=f"{describe(spec)} on {data.root.name}: {optimizer}, "
                                                  f"lr {lr:g}, batch {batch_size}")

    def run_validation(row: dict) -> None:
        if val_images is None:
            return
        v = validate(model, val_images, val_modes, val_targets, device)
        row["val_loss"] = v["val_loss"]
        row.update({f"val_mae_{n}": m for n, m in v["val_mae"].items()})
        shown = ", ".join(f"{n} {m:.3g}" for n, m in list(v["val_mae"].items())[:4])
        tqdm.write(f"iteration {state['iteration']}: train loss {row.get('train_loss', float('nan')):.4f}, "
                   f"val loss {v['val_loss']:.4f}, val MAE {shown}", file=sys.stderr)

    log(f"training {describe(spec)} ({sum(p.numel() for p in params):,} trainable parameters) on "
        f"{len(stream)} frames of {cfg.data} on {device}: {iterations} iterations of {batch_size}, "
        f"{optimizer} lr {lr:g} x{cfg.lr_gamma} every {cfg.lr_step}" + (f", {amp_dtype}" if amp_dtype else "")
        + (f"; {dist.world_size} processes ({torch.distributed.get_backend()}), {batch_size} samples each per "
           f"iteration, {batch_size * dist.world_size} in all" if dist.active else ""))
    loader_kw = dict(batch_size=batch_size, num_workers=cfg.workers, drop_last=True,
                     pin_memory=device.type == "cuda")
    if cfg.workers:
        loader_kw.update(worker_init_fn=_one_thread, prefetch_factor=4)
    loader = torch.utils.data.DataLoader(stream, **loader_kw)
    bar = tqdm(total=iterations, initial=state["iteration"], unit="it", dynamic_ncols=True, file=sys.stderr,
               mininterval=1.0 if sys.stderr.isatty() else 30.0, desc=cfg.model, disable=not dist.main)
    samples_per_it = batch_size * dist.world_size
    losses, t_row, t_start = [], time.perf_counter(), time.perf_counter() - state["seconds"]
    last_save = time.monotonic()
    try:
        with exit_on_sigterm(poll=True):
            while state["iteration"] < iterations:
                stream.set_epoch(state["epoch"])
                skip = state["step_in_epoch"]
                # several processes step together: an epoch ends for all at the fewest batches any rank has
                steps = dist.minimum(stream.batches(batch_size, cfg.workers)) if dist.active else None
                if steps == 0:
                    raise DatasetError(f"a process has no whole batch of {batch_size} in epoch {state['epoch']}: "
                                       f"too few training episodes of {cfg.data} for {dist.world_size} processes "
                                       f"and {max(cfg.workers, 1)} loader workers each")
                for step, (x, m, y) in enumerate(loader):
                    check_signals()
                    if steps is not None and step >= steps:
                        break
                    if step < skip:  # resuming: replay the epoch's order up to where the checkpoint left it
                        continue
                    x, m, y = (x.to(device, non_blocking=True), m.to(device, non_blocking=True),
                               y.to(device, non_blocking=True))
                    with torch.autocast(device.type, dtype=amp_dtype or torch.float32, enabled=amp_dtype is not None):
                        pred = net(x, m)
                    loss = euclidean_loss(pred, y)
                    if dist.active:   # the mean loss over ranks, and whether any rank is due to save, before backward
                        due = time.monotonic() - last_save > cfg.checkpoint_every
                        mean_loss, due = dist.mean([loss.item(), float(due)])
                        value, due = torch.tensor(mean_loss), due > 0
                    else:
                        value = loss
                    if not torch.isfinite(value):
                        raise TrainingError(f"the loss diverged ({value.item()}) at iteration {state['iteration']}; "
                                            f"lower --lr (now {lr:g}) or use --optimizer adam")
                    opt.zero_grad(set_to_none=True)
                    scaler.scale(loss).backward()
                    scaler.step(opt)
                    scaler.update()
                    sched.step()
                    state["iteration"] += 1
                    state["step_in_epoch"] = step + 1
                    losses.append(value.item())
                    it = state["iteration"]
                    bar.update(1)
                    if it % cfg.log_every == 0 or it == iterations or it % cfg.val_every == 0:
                        now = time.perf_counter()
                        state["seconds"] = now - t_start
                        row = {"iteration": it, "epoch": round(it * samples_per_it / len(stream), 3),
                               "train_loss": float(np.mean(losses)), "lr": opt.param_groups[0]["lr"],
                               "samples_per_s": round(len(losses) * samples_per_it / max(now - t_row, 1e-9), 2),
                               "elapsed_s": round(state["seconds"], 1)}
                        losses, t_row = [], now
                        bar.set_postfix(loss=f"{row['train_loss']:.4f}", lr=f"{row['lr']:.2g}",
                                        fps=f"{row['samples_per_s']:.0f}", refresh=False)
                        if it % cfg.val_every == 0 or it == iterations:
                            if dist.main:
                                run_validation(row)
                            state["history"].append(row)
                            save(final=it == iterations)
                            dist.barrier()   # the other ranks wait for rank 0's validation and checkpoint
                            last_save = time.monotonic()
                            t_row = time.perf_counter()  # validation and saving are not training time
                        else:
                            state["history"].append(row)
                    if (due if dist.active else time.monotonic() - last_save > cfg.checkpoint_every) \
                            and it < iterations:
                        state["seconds"] = time.perf_counter() - t_start
                        save()   # a kill between validations loses at most checkpoint_every seconds
                        dist.barrier()
                        last_save = time.monotonic()
                    if it >= iterations:
                        break
                else:
                    state["epoch"] += 1
                    state["step_in_epoch"] = 0
                    continue
                if steps is not None and state["iteration"] < iterations:   # this rank's share of the epoch is done
                    state["epoch"] += 1
                    state["step_in_epoch"] = 0
    except (KeyboardInterrupt, Terminated):
        bar.close()
        state["seconds"] = time.perf_counter() - t_start
        save()   # rank 0 only: the replicas are equal after every step
        log(f"interrupted: saved {out} at iteration {state['iteration']}; run the same command to continue")
        raise
    bar.close()
    log(f"saved {out} ({state['iteration']} iterations, {state['seconds'] / 60:.1f} min); loss curves in "
        f"{', '.join(str(p) for p in curve_paths(out))}")
    return {**state, "finished": True}


def _one_thread(_worker_id: int) -> None:  # decoding workers leave the cores to the training process
    torch.set_num_threads(1)


# --- GIST ---------------------------------------------------------------------------------------------------
@torch.no_grad()
def gist_descriptors(model: Regressor, root, split: str, labels, batch: int = 32, limit: int | None = None,
                     desc: str = "") -> tuple[torch.Tensor, torch.Tensor]:
    """GIST descriptors and normalised targets of a split (every frame, or `limit` spread over it)."""
    if limit is not None:
        images, modes, targets = load_frames(root, split, labels, limit)
        chunks = [(images[i:i + batch], modes[i:i + batch], targets[i:i + batch])
                  for i in range(0, len(images), batch)]
        total = len(images)
    else:
        stream = FrameStream(root, split, labels, shuffle=False)
        chunks = torch.utils.data.DataLoader(stream, batch_size=batch, num_workers=0)
        total = len(stream)
    feats, targets = [], []
    with tqdm(total=total, unit="frame", desc=desc, file=sys.stderr, dynamic_ncols=True,
              mininterval=1.0 if sys.stderr.isatty() else 30.0) as bar:
        for x, _, y in chunks:
            feats.append(model.net.descriptor(x.float() / 255.0))
            targets.append(y)
            bar.update(len(x))
    return torch.cat(feats), torch.cat(targets)


def fit_gist(cfg: TrainConfig, log=print) -> dict:
    """GIST + ridge: descriptors of every training frame, one closed-form solve per ridge strength, the
    strength chosen on the validation split (or on 10% of the training frames when there is none)."""
    data, decl, labels = open_data(cfg)
    out = Path(cfg.out)
    if out.exists():
        ckpt = load_checkpoint(out, model="gist", labels=labels, world=decl.name)
        if ckpt["spec"]["options"].get("regressor") != cfg.regressor:
            raise CheckpointError(f"{out} holds GIST + {ckpt['spec']['options'].get('regressor')}, not + "
                                  f"{cfg.regressor}; use another --out")
        log(f"{out} is a fitted GIST model already: nothing to do (remove it to fit again)")
        return ckpt["train"]
    if not data.frames("train"):
        raise DatasetError(f"dataset {cfg.data} has no frames in split 'train'")
    spec = make_spec("gist", decl, labels, regressor=cfg.regressor, seed=cfg.seed)
    model = Regressor(spec).eval()
    t0 = time.perf_counter()
    log(f"fitting {describe(spec)} on {data.frames('train')} frames of {cfg.data}")
    feats, targets = gist_descriptors(model, cfg.data, "train", labels, desc="GIST train")
    if data.frames("val"):
        val_feats, val_targets = gist_descriptors(model, cfg.data, "val", labels, limit=cfg.val_frames * 2,
                                                  desc="GIST val")
    else:
        log(f"note: {cfg.data} has no validation split; choosing the ridge strength on 10% of the training "
            "frames")
        held = torch.arange(len(feats)) % 10 == 9
        val_feats, val_targets, feats, targets = feats[held], targets[held], feats[~held], targets[~held]
    sweep = model.net.fit(feats, targets, val_feats, val_targets)
    best = min(sweep, key=lambda r: r["val_loss"])
    seconds = time.perf_counter() - t0
    log(f"ridge strength {best['alpha']:g}: train loss {best['train_loss']:.4f}, val loss {best['val_loss']:.4f} "
        f"({seconds:.0f} s)")
    config = {f.name: getattr(cfg, f.name) for f in fields(cfg)}
    record = {"iteration": 0, "epoch": 1, "step_in_epoch": 0, "history": sweep, "seconds": seconds,
              "config": config, "device": "cpu", "finished": True, "alpha": best["alpha"]}
    save_checkpoint(out, {"spec": spec, "state_dict": model.state_dict(), "train": record,
                          "data": data_summary(data)})
    write_curves(out, sweep, x="alpha", title=f"{describe(spec)} on {data.root.name}: ridge strength sweep")
    log(f"saved {out}; ridge sweep in {', '.join(str(p) for p in curve_paths(out))}")
    return record


def config_from(**kwargs) -> TrainConfig:
    """A TrainConfig from keyword arguments, ignoring those that are not its fields (e.g. argparse extras)."""
    names = {f.name for f in fields(TrainConfig)}
    return TrainConfig(**{k: v for k, v in kwargs.items() if k in names})

