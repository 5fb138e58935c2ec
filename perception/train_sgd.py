"""The SGD trainer of the regressors (AlexNet, VGG-16, MobileNet, any family whose trainer is "sgd"), configured by
perception/training.py's TrainConfig: a step of perception/trainer.py's protocol is one optimiser step on a batch,
and the driver's loop (perception/train.py) runs them, in the manner of nanoGPT's train.py.

The checkpoint at `out` is written atomically at every validation, every `checkpoint_every` seconds, at the end
and on Ctrl-C or SIGTERM; running the same training again continues from it (same data order, same optimiser
state). Loss curves go beside it as `<out>.loss.csv` and `<out>.loss.png`.

Precision (`amp`, the default): the forward pass runs under autocast where its arithmetic is fast, bfloat16 on a CPU
that computes it natively (AVX512-BF16 or AMX: perception/precision.py's bf16_native) as Z2Color's trainer does, and
on CUDA bfloat16 or float16; the master weights, the optimiser, the loss and its reduction stay float32, and so does
validation (the drivers run the networks in float32). Elsewhere, and with `amp` false, float32 throughout. The
checkpoint's train record names the precision (`precision`); a run continued in another one says so.

Several processes (torchrun, perception/distributed.py): each rank trains a DistributedDataParallel copy of the
model on a disjoint part of the training episodes every epoch (the same shuffled order everywhere, FrameStream's
rank split) with batches of `batch_size`: the effective batch is world_size x batch_size. The ranks run the same
number of iterations; the logged loss is the mean over ranks; rank 0 alone validates and writes the checkpoint
and curves (in the same format as a single process) while the others wait. docs/scaling.md.
"""
from __future__ import annotations

import math
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, fields
from pathlib import Path
from typing import ClassVar, cast

import numpy as np
import torch
from tqdm import tqdm

from core.children import worker_initializer
from core.declaration import WorldDeclaration
from perception.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from perception.curves import curve_paths, write_curves
from perception.datasets import FrameStream, collate_channels_last
from perception.distributed import Distributed
from perception.frame_cache import FrameCache, prepare_cache
from perception.models import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    Regressor,
    add_renderers,
    check_spec,
    describe,
    family,
    frame_inset,
    load_trunk,
    make_spec,
)
from perception.optimizers import make_optimizer as optimizer
from perception.precision import bf16_native
from perception.shards import Dataset, DatasetError
from perception.trainer import Occasion, Plan
from perception.training import (
    LOSSES,
    TrainConfig,
    TrainingError,
    data_summary,
    history_moment,
    input_statistics,
    load_frames,
    validate,
)
from perception.weight_average import WeightAverage


@dataclass
class Setup:
    """The run's numbers and model, from the config, the family's paper defaults and the checkpoint it continues."""

    iterations: int
    batch_size: int
    lr: float
    optimizer: str
    loss: str               # a name of LOSSES
    ema: float              # decay of the weights' moving average, 0 for none (perception/weight_average.py)
    spec: dict
    ckpt: dict | None       # the checkpoint at `out` this run continues, or None
    init: dict | None = None   # the checkpoint a new run starts from (--init), or None


def plan_run(cfg: TrainConfig, data: Dataset, decl: WorldDeclaration, labels, stream: FrameStream,
             dist: Distributed, log) -> Setup:
    """The run's numbers and the model spec; a checkpoint at `out` is checked against the options first."""
    paper = family(cfg.model).defaults
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
    loss = cfg.loss or paper.get("loss", "euclidean")
    ema = cfg.ema if cfg.ema is not None else paper.get("ema", 0.0)
    out = Path(cfg.out)
    if not out.exists() and cfg.init:
        init = initial_checkpoint(cfg, decl, labels)   # fine-tuning keeps the loss the model learned under
        loss = cfg.loss or init.get("train", {}).get("config", {}).get("loss") or "euclidean"
        spec = add_renderers(init["spec"], data.renderers)   # it learns this data's frames too
        return Setup(iterations, batch_size, lr, optimizer, loss, ema, spec, None, init)
    if not out.exists():
        spec = add_renderers(new_spec(cfg, decl, labels, dist, log), data.renderers)
        return Setup(iterations, batch_size, lr, optimizer, loss, ema, spec, None)
    ckpt = load_checkpoint(out, model=cfg.model, labels=labels, world=decl.name)
    check_spec(ckpt["spec"], str(out))
    if "optimizer" not in ckpt:
        raise CheckpointError(f"{out} holds no training state to continue from")
    check_continuation(cfg, decl, ckpt, optimizer, ema)
    old = ckpt["train"]["config"]
    loss = old.get("loss") or "euclidean"   # checkpoints from before the setting loss were all Euclidean
    if old.get("lr") != lr or old.get("batch_size") != batch_size:
        log(f"note: {out} continues with its own learning-rate schedule (started at lr {old.get('lr'):g}, "
            f"batch {old.get('batch_size')}); the settings of this run are ignored")
        lr, batch_size = old.get("lr", lr), old.get("batch_size", batch_size)
    return Setup(iterations, batch_size, lr, optimizer, loss, ema, ckpt["spec"], ckpt)


def earlier_frames(decl: WorldDeclaration, history: int) -> int:
    """How many earlier frames a model trained with the setting history reads (0: the world's own data moment)."""
    return history or len(decl.moment.instants) - 1


def check_continuation(cfg: TrainConfig, decl: WorldDeclaration, ckpt: dict, optimizer: str, ema: float) -> None:
    """A checkpoint is continued only with the settings it was trained with."""
    out, o = cfg.out, ckpt["spec"]["options"]
    if cfg.model == "vgg16" and o.get("frozen") == cfg.unfreeze:
        raise CheckpointError(f"{out} was trained with unfreeze={str(not o.get('frozen')).lower()}; "
                              "use the same settings to continue it, or another --out")
    if cfg.model == "vgg16" and bool(o.get("batch_norm")) != cfg.batch_norm:
        raise CheckpointError(f"{out} was trained with batch_norm="
                              f"{str(bool(o.get('batch_norm'))).lower()}; use the same settings to continue it, or "
                              "another --out")
    if len(ckpt["spec"]["input"]["instants"]) - 1 != earlier_frames(decl, cfg.history):
        raise CheckpointError(f"{out} reads {len(ckpt['spec']['input']['instants']) - 1} earlier frame(s); continue "
                              "it with the same history, or use another --out")
    check_inset(str(out), ckpt["spec"], decl)
    old = ckpt["train"]["config"]
    if old.get("optimizer") != optimizer:
        raise CheckpointError(f"{out} was trained with optimizer={old.get('optimizer')}; use the same "
                              "optimiser to continue it, or another --out")
    if cfg.loss and cfg.loss != (old.get("loss") or "euclidean"):
        raise CheckpointError(f"{out} was trained with loss={old.get('loss') or 'euclidean'}; use the same loss "
                              "to continue it, or another --out")
    if ema != (old.get("ema") or 0.0):
        raise CheckpointError(f"{out} was trained with ema={old.get('ema') or 0:g}; use the same moving average "
                              "to continue it, or another --out")


def check_inset(where: str, spec: dict, decl: WorldDeclaration) -> None:
    """A model goes on learning only frames like the ones it learned: with the same inset (the rear-view mirror,
    the side views) or without one."""
    had, has = frame_inset(spec), decl.cameras[0].inset
    if had != has:
        raise CheckpointError(f"{where} learned frames {f'with the {had} inset' if had else 'without an inset'}; this "
                              f"data's frames are {f'with the {has} inset' if has else 'without one'}: use data like "
                              "its own, or another --out")


def initial_checkpoint(cfg: TrainConfig, decl: WorldDeclaration, labels) -> dict:
    """The checkpoint a fine-tuning run starts from: the same family, world, targets and earlier frames; its input
    statistics and weights are kept (a new optimiser and schedule start)."""
    init = load_checkpoint(cfg.init, model=cfg.model, labels=labels, world=decl.name)
    check_spec(init["spec"], str(cfg.init))
    check_inset(f"--init {cfg.init}", init["spec"], decl)
    if len(init["spec"]["input"]["instants"]) - 1 != earlier_frames(decl, cfg.history):
        raise CheckpointError(f"--init {cfg.init} reads {len(init['spec']['input']['instants']) - 1} earlier "
                              f"frame(s), not history={cfg.history}")
    return init


def new_spec(cfg: TrainConfig, decl: WorldDeclaration, labels, dist: Distributed, log) -> dict:
    """The spec of a new model: its input statistics (ImageNet's with ImageNet weights, else the data's)."""
    if cfg.weights:  # ImageNet weights expect ImageNet's input statistics
        mean, std, weights = IMAGENET_MEAN, IMAGENET_STD, "imagenet"
    else:
        log("computing the per-channel input mean and deviation of the training frames ...")
        moment = history_moment(decl, cfg.history)
        mean, std = dist.share(input_statistics(cfg.data, labels, moment=moment) if dist.main else None)
        weights = None
    options: dict = {"weights": weights}
    if cfg.model == "vgg16":
        options.update(frozen=not cfg.unfreeze, batch_norm=cfg.batch_norm)
    instants = tuple(range(-cfg.history, 1)) if cfg.history else None
    return make_spec(cfg.model, decl, labels, mean=mean, std=std, instants=instants, **options)


def build_model(cfg: TrainConfig, setup: Setup, device: torch.device, log) -> Regressor:
    """The model: the checkpoint's weights, a trunk of ImageNet weights, or a fresh initialisation."""
    model = Regressor(setup.spec)
    if setup.ckpt is not None:   # with a moving average, "state_dict" holds the average, not the trained weights
        model.load_state_dict(setup.ckpt.get("training_state_dict", setup.ckpt["state_dict"]))
    elif setup.init is not None:
        model.load_state_dict(setup.init["state_dict"])
        log(f"{cfg.model}: starting from the weights of {cfg.init}")
    elif cfg.weights:
        n = load_trunk(model, cfg.weights)
        log(f"{cfg.model} trunk: {n} tensors of ImageNet weights from {cfg.weights}")
    elif cfg.model == "vgg16":
        log("VGG-16 trunk: no --weights given, so the convolutional layers start from RANDOM initialisation "
            "(nothing is downloaded; pass --weights vgg16-397923af.pth for the paper's ImageNet start)"
            + ("; they stay frozen, so only the head learns" if not cfg.unfreeze else ""))
    model.to(device)
    model.train()
    return model


def make_optimizer(name: str, params, lr: float, cfg: TrainConfig) -> torch.optim.Optimizer:
    try:
        return optimizer(name, params, lr, cfg.momentum, cfg.weight_decay)
    except ValueError as e:
        raise TrainingError(str(e)) from None


def frame_cache(data: Dataset, dist: Distributed, log) -> FrameCache:
    """The training split's frames decoded once (rank 0 decodes; the other ranks wait and read)."""
    if dist.main:
        prepare_cache(data, data.select("train"), log=log)
    dist.barrier()
    return FrameCache(data)


def amp_dtype(cfg: TrainConfig, device: torch.device, log) -> torch.dtype | None:
    """The dtype of the forward pass's autocast, None for float32 throughout (`amp` false, or a CPU without native
    bfloat16, where oneDNN emulates it several times slower than float32): on CUDA bfloat16 where supported, else
    float16 (with the gradient scaler); on a CPU bfloat16 where it is native (AVX512-BF16 or AMX), as Z2Color's
    trainer does. The master weights, the optimiser, the loss and its reduction stay float32 either way."""
    if not cfg.amp:
        return None
    if device.type == "cuda":
        return torch.bfloat16 if torch.cuda.is_bf16_supported() else torch.float16
    if bf16_native(device):
        return torch.bfloat16
    log(f"bfloat16 is not native on this {device.type} (no AVX512-BF16 or AMX): training in float32, which is "
        "faster here")
    return None


def precision(dtype: torch.dtype | None) -> str:
    """The name a checkpoint's train record gives the arithmetic of the forward pass: float32, bfloat16 or float16."""
    return str(dtype or torch.float32).removeprefix("torch.")


def _one_thread(worker_id: int) -> None:  # decoding workers leave the cores to the training process
    worker_initializer(worker_id)   # and die with it
    torch.set_num_threads(1)


class SGDTrainer:
    """The SGD trainer (perception/trainer.py's protocol): the model, its optimiser and schedule, the state a
    checkpoint carries. A step is one optimiser step on a batch."""

    repeats: ClassVar[bool] = True
    reads: ClassVar[frozenset[str]] = frozenset({
        "iterations", "epochs", "batch_size", "lr", "lr_step", "lr_gamma", "optimizer", "loss", "ema", "momentum",
        "weight_decay", "amp", "workers", "shuffle_buffer", "val_every", "checkpoint_every", "val_frames", "log_every",
        "weights", "init", "cache", "channels_last", "emphasis"})

    def __init__(self, cfg: TrainConfig, data: Dataset, decl: WorldDeclaration, labels, device: torch.device,
                 dist: Distributed, log):
        self.cfg, self.data, self.decl, self.labels, self.device, self.dist, self.log = \
            cfg, data, decl, labels, device, dist, log
        self.out = Path(cfg.out)
        self.state: dict = {"iteration": 0, "epoch": 0, "step_in_epoch": 0, "history": [], "seconds": 0.0}
        self.val: tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None = None   # images, modes, targets
        self.losses: list[float] = []            # the training losses since the last row of the curve
        self.t_start = self.t_row = time.perf_counter()
        self.last_save = time.monotonic()
        self.bar = tqdm(total=0, disable=True)      # the progress bar, from restore()

    # --- the protocol ------------------------------------------------------------------------------------------
    def plan(self) -> Plan:
        """The run's numbers and the model, its optimiser and schedule; nothing to do when the checkpoint at `out`
        has every iteration already."""
        cfg, data, dist, log = self.cfg, self.data, self.dist, self.log
        torch.manual_seed(cfg.seed)
        self.moment = history_moment(self.decl, cfg.history)
        self.stream = FrameStream(cfg.data, "train", self.labels, shuffle=True, seed=cfg.seed,
                                  buffer=min(cfg.shuffle_buffer, data.frames("train")), rank=dist.rank,
                                  world_size=dist.world_size, moment=self.moment,
                                  cache=frame_cache(data, dist, log) if cfg.cache else None, emphasis=cfg.emphasis)
        self.setup = setup = plan_run(cfg, data, self.decl, self.labels, self.stream, dist, log)
        if setup.ckpt is not None and setup.ckpt["train"]["iteration"] >= setup.iterations:
            log(f"{self.out} has already trained {setup.ckpt['train']['iteration']} of {setup.iterations} "
                "iterations: nothing to do (raise --iterations to train further)")
            return Plan(done=setup.ckpt["train"])
        self.model = build_model(cfg, setup, self.device, log)
        self.channels_last = cfg.channels_last and self.device.type == "cpu"
        if self.channels_last:   # oneDNN's convolutions are faster on channels-last weights and inputs
            self.model.to(memory_format=torch.channels_last)
            self.stream.channels_last = True   # batches come channels-last: step's conversion copies nothing
        self.net: torch.nn.Module = self.model   # what the steps call: the model or its DistributedDataParallel
        if dist.active:
            self.net = torch.nn.parallel.DistributedDataParallel(
                self.model, device_ids=[self.device.index] if self.device.type == "cuda" else None)
        self.params = [p for p in self.model.parameters() if p.requires_grad]
        self.opt = make_optimizer(setup.optimizer, self.params, setup.lr, cfg)
        self.sched = torch.optim.lr_scheduler.StepLR(self.opt, step_size=cfg.lr_step, gamma=cfg.lr_gamma)
        self.average = WeightAverage(self.model, setup.ema) if setup.ema else None
        self.amp_dtype = amp_dtype(cfg, self.device, log)
        self.scaler = torch.amp.GradScaler("cuda", enabled=self.amp_dtype == torch.float16)
        return Plan(steps=setup.iterations, validate_every=cfg.val_every)

    def restore(self) -> Iterator[tuple[int, tuple]]:
        """Continue the checkpoint's optimiser, schedule and RNG; the batches still to train on."""
        ckpt, out = self.setup.ckpt, self.out
        if ckpt is not None:
            self.opt.load_state_dict(ckpt["optimizer"])
            self.sched.load_state_dict(ckpt["scheduler"])
            if self.average is not None:
                self.average.load(ckpt["state_dict"], ckpt["train"].get("averaged_steps", 0))
            if "scaler" in ckpt and self.scaler.is_enabled():
                self.scaler.load_state_dict(ckpt["scaler"])
            if "rng" in ckpt:
                torch.set_rng_state(ckpt["rng"])
            self.state.update({k: ckpt["train"][k] for k in self.state})
            if ckpt["train"].get("world_size", 1) != self.dist.world_size:
                self.log(f"note: {out} was trained by {ckpt['train'].get('world_size', 1)} process(es), this run "
                         f"has {self.dist.world_size}: the data order from here on differs from an uninterrupted run")
            trained = ckpt["train"].get("precision")   # None: a checkpoint from before the record had it
            if trained is not None and trained != precision(self.amp_dtype):
                self.log(f"note: {out} was trained in {trained}, this run trains in {precision(self.amp_dtype)}: the "
                         "weights from here on differ from an uninterrupted run's")
            if ckpt["data"]["frames"] != data_summary(self.data)["frames"]:
                self.log(f"note: {out} was trained on data with {ckpt['data']['frames']} frames per split; "
                         f"continuing on {self.cfg.data} with {data_summary(self.data)['frames']}")
            self.log(f"continuing {out} from iteration {self.state['iteration']} of {self.setup.iterations}")
        self.load_validation()
        self.announce()
        loader = self.loader()
        self.bar = tqdm(total=self.setup.iterations, initial=self.state["iteration"], unit="it", dynamic_ncols=True,
                        file=sys.stderr, mininterval=1.0 if sys.stderr.isatty() else 30.0, desc=self.cfg.model,
                        disable=not self.dist.main)
        self.losses = []
        self.t_row = time.perf_counter()
        self.t_start = time.perf_counter() - self.state["seconds"]
        self.last_save = time.monotonic()
        return self.batches(loader)

    def step(self, work: tuple) -> bool:
        """One optimiser step on a batch (work: its index in the epoch and the batch), counted; a row of the loss
        curve when one is due. Whether a save is due by the clock: with several ranks, whether any rank is, agreed
        before backward."""
        index, (x, m, y) = work
        loss, due = self.optimise(x, m, y)
        st, it_max = self.state, self.setup.iterations
        st["iteration"] += 1
        st["step_in_epoch"] = index + 1
        it = st["iteration"]
        self.losses.append(loss)
        self.bar.update(1)
        if it % self.cfg.log_every == 0 or it == it_max or it % self.cfg.val_every == 0:
            st["history"].append(self.curve_row(it))
        if due is None:   # one process: due when the last save is older than checkpoint_every
            due = time.monotonic() - self.last_save > self.cfg.checkpoint_every
        return due

    def validate(self) -> None:
        """The validation loss and MAE into this iteration's row of the curve (rank 0 validates)."""
        row = self.state["history"][-1]
        if self.val is None or not self.dist.main:
            return
        images, modes, targets = self.val
        v = validate(self.used(), images, modes, targets, self.device, loss=self.setup.loss)
        row["val_loss"] = v["val_loss"]
        row.update({f"val_mae_{n}": m for n, m in v["val_mae"].items()})
        shown = ", ".join(f"{n} {m:.3g}" for n, m in list(v["val_mae"].items())[:4])
        tqdm.write(f"iteration {self.state['iteration']}: train loss {row.get('train_loss', float('nan')):.4f}, "
                   f"val loss {v['val_loss']:.4f}, val MAE {shown}", file=sys.stderr)

    def save(self, occasion: Occasion) -> dict:
        """The checkpoint and the curves (rank 0 writes; the other ranks wait for it, but on an interruption)."""
        st = self.state
        if occasion in ("clock", "interrupt"):   # a validation's row has timed the run already
            st["seconds"] = time.perf_counter() - self.t_start
        if occasion == "interrupt":
            self.bar.close()
            self.write(final=False)   # rank 0 only: the replicas are equal after every step
            self.log(f"interrupted: saved {self.out} at iteration {st['iteration']}; run the same command to "
                     "continue")
            return st
        self.write(final=occasion == "end")
        self.dist.barrier()   # the other ranks wait for rank 0's validation and checkpoint
        self.last_save = time.monotonic()
        if occasion != "clock":
            self.t_row = time.perf_counter()   # validation and saving are not training time
        if occasion != "end":
            return st
        self.bar.close()
        self.log(f"saved {self.out} ({st['iteration']} iterations, {st['seconds'] / 60:.1f} min); "
                 f"loss curves in {', '.join(str(p) for p in curve_paths(self.out))}")
        return {**st, "finished": True}

    # --- the steps' parts --------------------------------------------------------------------------------------
    def batches(self, loader) -> Iterator[tuple[int, tuple]]:
        """The batches still to train on, epoch after epoch from where the checkpoint left off: (the iterations
        done once it is trained on, (its index in the epoch, the batch))."""
        st, dist, setup = self.state, self.dist, self.setup
        while st["iteration"] < setup.iterations:
            self.stream.set_epoch(st["epoch"])
            skip = st["step_in_epoch"]
            # several processes step together: an epoch ends for all at the fewest batches any rank has
            steps = dist.minimum(self.stream.batches(setup.batch_size, self.cfg.workers)) if dist.active else None
            if steps == 0:
                raise DatasetError(f"a process has no whole batch of {setup.batch_size} in epoch {st['epoch']}: "
                                   f"too few training episodes of {self.cfg.data} for {dist.world_size} processes "
                                   f"and {max(self.cfg.workers, 1)} loader workers each")
            for index, batch in enumerate(loader):
                if steps is not None and index >= steps:
                    break
                if index < skip:  # resuming: replay the epoch's order up to where the checkpoint left it
                    continue
                yield st["iteration"] + 1, (index, batch)
                if st["iteration"] >= setup.iterations:
                    return
            st["epoch"] += 1
            st["step_in_epoch"] = 0

    def optimise(self, x, m, y) -> tuple[float, bool | None]:
        """One optimiser step on a batch: (the loss, mean over ranks; with several ranks, whether any is due to
        save, agreed before backward)."""
        dev = self.device
        x, m, y = x.to(dev, non_blocking=True), m.to(dev, non_blocking=True), y.to(dev, non_blocking=True)
        if self.channels_last:
            x = x.contiguous(memory_format=torch.channels_last)
        with torch.autocast(dev.type, dtype=self.amp_dtype or torch.float32, enabled=self.amp_dtype is not None):
            pred = self.net(x, m)
        loss = LOSSES[self.setup.loss](pred, y)
        value, due = loss, None
        if self.dist.active:   # the mean loss over ranks, and whether any rank is due to save, before backward
            late = time.monotonic() - self.last_save > self.cfg.checkpoint_every
            mean_loss, due_any = self.dist.mean([loss.item(), float(late)])
            value, due = torch.tensor(mean_loss), due_any > 0
        if not torch.isfinite(value):
            raise TrainingError(f"the loss diverged ({value.item()}) at iteration {self.state['iteration']}; "
                                f"lower --lr (now {self.setup.lr:g}) or use --set optimizer=adam")
        self.opt.zero_grad(set_to_none=True)
        self.scaler.scale(loss).backward()
        self.scaler.step(self.opt)
        self.scaler.update()
        self.sched.step()
        if self.average is not None:
            self.average.update(self.model)
        return value.item(), due

    def curve_row(self, it: int) -> dict:
        now = time.perf_counter()
        self.state["seconds"] = now - self.t_start
        per_it = self.setup.batch_size * self.dist.world_size
        row = {"iteration": it, "epoch": round(it * per_it / len(self.stream), 3),
               "train_loss": float(np.mean(self.losses)), "lr": self.opt.param_groups[0]["lr"],
               "samples_per_s": round(len(self.losses) * per_it / max(now - self.t_row, 1e-9), 2),
               "elapsed_s": round(self.state["seconds"], 1)}
        self.losses, self.t_row = [], now
        self.bar.set_postfix(loss=f"{row['train_loss']:.4f}", lr=f"{row['lr']:.2g}",
                             fps=f"{row['samples_per_s']:.0f}", refresh=False)
        return row

    def load_validation(self) -> None:
        if self.data.frames("val") and self.dist.main:   # rank 0 validates
            self.val = load_frames(self.cfg.data, "val", self.labels, self.cfg.val_frames, moment=self.moment)
        elif not self.data.frames("val"):
            self.log(f"note: {self.cfg.data} has no validation split (episodes 8, 18, ...); training without "
                     "validation")

    def announce(self) -> None:
        cfg, setup, dist = self.cfg, self.setup, self.dist
        self.log(f"training {describe(setup.spec)} ({sum(p.numel() for p in self.params):,} trainable parameters) "
                 f"on {len(self.stream)} frames of {cfg.data}"
                 + (f" (its decisive frames {cfg.emphasis} times each)" if cfg.emphasis != 1 else "")
                 + f" on {self.device}: {setup.iterations} iterations of "
                 f"{setup.batch_size}, {setup.loss} loss, {setup.optimizer} lr {setup.lr:g} x{cfg.lr_gamma} every "
                 f"{cfg.lr_step}"
                 + (f", {precision(self.amp_dtype)} autocast" if self.amp_dtype else "")
                 + (f"; {dist.world_size} processes ({torch.distributed.get_backend()}), {setup.batch_size} samples "
                    f"each per iteration, {setup.batch_size * dist.world_size} in all" if dist.active else ""))

    def loader(self) -> torch.utils.data.DataLoader:
        kw: dict = dict(batch_size=self.setup.batch_size, num_workers=self.cfg.workers, drop_last=True,
                        pin_memory=self.device.type == "cuda")
        if self.cfg.workers:
            kw.update(worker_init_fn=_one_thread, prefetch_factor=4)
        if self.stream.channels_last:
            kw.update(collate_fn=collate_channels_last)
        return torch.utils.data.DataLoader(self.stream, **kw)

    def write(self, final: bool) -> None:
        """The checkpoint and the curves, by rank 0."""
        if not self.dist.main:
            return
        cfg, setup = self.cfg, self.setup
        config = {f.name: getattr(cfg, f.name) for f in fields(cfg)}
        config.update(iterations=setup.iterations, batch_size=setup.batch_size, lr=setup.lr,
                      optimizer=setup.optimizer, loss=setup.loss, ema=setup.ema)
        payload: dict = {"spec": setup.spec, "state_dict": self.used().state_dict(),
                         "optimizer": self.opt.state_dict(), "scheduler": self.sched.state_dict(),
                         "rng": torch.get_rng_state(),
                         "train": {**self.state, "config": config, "device": str(self.device),
                                   "precision": precision(self.amp_dtype), "finished": final},
                         "data": data_summary(self.data)}
        if self.average is not None:   # the weights it trains, to continue from; the average is what is used
            payload["training_state_dict"] = self.model.state_dict()
            payload["train"]["averaged_steps"] = self.average.steps
        if self.dist.active:
            payload["train"]["world_size"] = self.dist.world_size
        if self.scaler.is_enabled():
            payload["scaler"] = self.scaler.state_dict()
        save_checkpoint(self.out, payload)
        title = f"{describe(setup.spec)} on {self.data.root.name}: {setup.loss} loss, {setup.optimizer}, " \
                f"lr {setup.lr:g}, batch {setup.batch_size}"
        write_curves(self.out, self.state["history"], title=title)

    def used(self) -> Regressor:
        """The model the run validates and saves: the moving average of the weights where there is one."""
        return self.model if self.average is None else cast(Regressor, self.average.module)
