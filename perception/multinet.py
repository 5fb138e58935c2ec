"""Training of Z2Color as MultiNet and as its MTL baselines (Chowdhuri, Pankaj and Zipser, MultiNet: Multi-Modal
Multi-Task Learning for Autonomous Driving, 2017), with the paper's measures.

- Data: data moments of one or more datasets of one world (perception/moments.py: images at the network's
  94 x 168, decoded once per dataset and cached beside it; a moment is an index).
- Held-out data: 10 % of the episodes of each behavioural mode (at least one), whole episodes, with every mode
  equally represented (the larger modes' held-out moments are subsampled to the smallest's count).
- Training: Adadelta; the loss over all 20 outputs, 1/(2n) sum_t (s'_t - s_t)^2 + (m'_t - m_t)^2 with n = 10 (the
  paper's equation 1); the gradient norm clipped at 1.0; batches with the modes equally represented.
- Validation: the loss on the last step only, 1/2 ((s'_10 - s_10)^2 + (m'_10 - m_10)^2) (equation 2), per epoch,
  over all held-out moments and per mode, in float32.
- Trials: `trials` repeats with fresh seeds (initialisation and shuffling); `<out>.loss.csv` / `.loss.png` hold the
  mean over trials per epoch with its 95 % confidence half-width (Student's t). The saved model is the one at the
  epoch and trial with the lowest validation loss, as the paper chose its cars' networks.
- MultiNet trains on every mode with the modal input; an MTL net (`mtl=MODE`) is the same network without the modal
  input, trained and validated on one mode's data.
- Targets must be the expert's: moments whose future steps include one a network drove are left out; the expert's
  corrections stay in (the paper's DAgger variant).

Speed on a CPU (docs/benchmarks.md): the weights and the images are channels-last (oneDNN's preferred layout), the
forward and backward passes run under bfloat16 autocast where the processor computes bfloat16 natively (`amp`, the
default: AVX512-BF16 or AMX, or a CUDA device that supports it; float32 master weights, the losses and the optimiser
in float32; validation's forward pass under the same autocast); elsewhere, and with `amp` false, float32 throughout
(emulated bfloat16 trains several times slower); a second thread assembles the next batch while the present one
trains, its pixels scaled through a table of the 256 values as they are gathered (Regressor.pixel_table,
Moments.looked_up: bit for bit scale_input's).

A run is resumable at epoch granularity: its state is saved beside the model (`<out>.state`) after every epoch and
on Ctrl-C or SIGTERM; the same command continues it.
"""
from __future__ import annotations

import math
import queue
import sys
import threading
import time
from collections.abc import Iterable, Iterator
from contextlib import nullcontext
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch

from core.declaration import DeclarationError, WorldDeclaration
from core.signals import check as check_signals
from perception.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from perception.curves import write_curves
from perception.models import Regressor, add_renderers, family, make_spec
from perception.moments import Moments
from perception.optimizers import make_optimizer as optimizer
from perception.precision import bf16_native
from perception.train_outputs import state_path
from perception.trainer import Occasion, Plan
from perception.training import open_data, resolve_device

CLIP = 1.0                 # gradient norm (the authors' code)
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262, 10: 2.228,
       15: 2.131, 20: 2.086, 30: 2.042}   # Student's t, two-sided 95 %, by degrees of freedom


# --- the paper's measures ----------------------------------------------------------------------------------------
def train_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Equation 1: 1/(2n) * sum over the n steps of the squared steering and motor errors, averaged over the batch
    (outputs are n steering values then n motor values, so this is the sum over all 2n outputs divided by 2n)."""
    n = pred.shape[1] // 2
    return ((pred.float() - target.float()) ** 2).sum(1).mean() / (2 * n)


def validation_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Equation 2, per moment: 1/2 ((s'_n - s_n)^2 + (m'_n - m_n)^2), the last step's steering and motor only."""
    n = pred.shape[1] // 2
    last = [n - 1, 2 * n - 1]
    return ((pred[:, last].float() - target[:, last].float()) ** 2).sum(1) / 2


def t95(dof: int) -> float:
    if dof <= 0:
        return math.nan
    return T95[max(k for k in T95 if k <= dof)]


def summarise_trials(history: list[dict], keys) -> list[dict]:
    """Per epoch: the mean over trials and its 95 % confidence half-width of each key."""
    out = []
    for e in sorted({r["epoch"] for r in history}):
        rows = [r for r in history if r["epoch"] == e]
        row = {"epoch": e, "trials": len(rows)}
        for k in keys:
            vals = np.array([r[k] for r in rows if r.get(k) is not None], dtype=np.float64)
            if not len(vals):
                continue
            row[f"{k}_mean"] = float(vals.mean())
            row[f"{k}_ci95"] = float(t95(len(vals) - 1) * vals.std(ddof=1) / math.sqrt(len(vals))) \
                if len(vals) > 1 else None
        out.append(row)
    return out


def balanced_batches(train: dict, batch: int, rng: np.random.Generator, batches: int, steering: dict | None = None,
                     share: float = 0.0) -> Iterator[np.ndarray]:
    """`batches` batches of `batch` moments, each mode an equal share (each mode's pool shuffled and cycled); with
    `steering` ({mode: its steering moments}) and `share`, that share of each mode's part (rounded) is drawn from
    its steering moments, the rest from all of them."""
    modes = sorted(train)
    per = max(1, batch // len(modes))
    steering = steering if share > 0 else None
    pools = {(m, "all"): train[m] for m in modes}
    for m in modes:   # (inserted after every mode's whole pool: with no share the draws are as they always were)
        if steering is not None and len(steering.get(m, ())):
            pools[(m, "steer")] = steering[m]
    takes = {}
    for m in modes:
        steer = int(round(per * share)) if (m, "steer") in pools else 0
        takes[(m, "all")], takes[(m, "steer")] = per - steer, steer
    order = {key: rng.permutation(ids) for key, ids in pools.items()}
    pos = {key: 0 for key in pools}
    for _ in range(batches):
        ids = []
        for m in modes:
            for key in ((m, "all"), (m, "steer")):
                if key not in pools or not takes[key]:
                    continue
                n = takes[key]
                if pos[key] + n > len(order[key]):
                    order[key], pos[key] = rng.permutation(pools[key]), 0
                take = order[key][pos[key]:pos[key] + n]
                if len(take) < n:   # a pool smaller than its share: draw with replacement
                    take = rng.choice(pools[key], n, replace=True)
                ids.append(take)
                pos[key] += n
        yield np.concatenate(ids)


STEERING = 0.1   # a steering moment: its actuated (last) steering target at least this far from straight ahead (0.5)


def steering_moments(moments: Moments, train: dict, outputs) -> dict:
    """{mode: the training moments whose actuated steering target (the last steer+k) is a steering one}."""
    k = max(i for i, name in enumerate(outputs) if name.startswith("steer+"))
    turning = np.abs(moments.targets[:, k] - 0.5) >= STEERING
    return {m: ids[turning[ids]] for m, ids in train.items()}


# --- the run's settings and progress -----------------------------------------------------------------------------
@dataclass
class MultiNetRun:
    """Everything one training run is, resolved from the TrainConfig (perception/train.py) and the data."""

    roots: list[str]
    out: Path
    names: list[str]                 # the behavioural modes trained on (one for an MTL net)
    mtl: str | None
    epochs: int
    trials: int
    batch: int
    mode_moments: int | None         # an epoch's cap per mode (short fine-tuning on a growing set); None: all
    lr: float
    optimizer: str
    seed: int
    device: torch.device
    amp: bool                        # bfloat16 autocast of forward and backward
    init: str | None
    spec: dict
    moments: Moments
    train_ids: dict
    held: np.ndarray
    config: dict
    steer_share: float = 0.0         # share of each mode's draws from its steering moments (balanced_batches)
    steering: dict = field(default_factory=dict)

    @property
    def title(self) -> str:
        return f"{'MTL ' + self.mtl if self.mtl else 'MultiNet'} on {', '.join(self.names)}"

    @property
    def state_path(self) -> Path:
        return state_path(self.out)

    @property
    def steps(self) -> int:
        total = sum(len(v) for v in self.train_ids.values())
        if self.mode_moments is not None:
            total = min(total, self.mode_moments * len(self.train_ids))
        return max(1, total // self.batch)

    def describe(self) -> str:
        n_train = sum(len(v) for v in self.train_ids.values())
        params = sum(p.numel() for p in Regressor(self.spec).parameters())
        return (f"training {self.title}: Z2Color, {params:,} parameters; {n_train} training and {len(self.held)} "
                f"held-out moments; {self.trials} trial(s) x {self.epochs} epochs of {self.steps} batches of "
                f"{self.batch}{'' if self.mode_moments is None else f' (at most {self.mode_moments} per mode)'}, "
                f"{self.optimizer} lr {self.lr:g}, gradient norm clipped at {CLIP} on {self.device}"
                f"{' (bfloat16 autocast)' if self.amp else ''}"
                + (f"; {self.steer_share:.0%} of each mode's draws from its {sum(map(len, self.steering.values()))} "
                   f"steering moments" if self.steer_share else ""))


@dataclass
class Progress:
    """Where a run stands (saved in `<out>.state` and, finished, in the checkpoint's `train` record)."""

    trial: int = 0
    epoch: int = 0
    history: list = field(default_factory=list)
    best: dict | None = None
    seconds: float = 0.0


def run_modes(cfg, decl: WorldDeclaration) -> list[str]:
    """The modes a run trains on: cfg.mtl's one, else cfg.modes' (None: all the world's). A list that names no
    mode ("", ",") is refused, not read as all of them; so is an unknown mode."""
    if cfg.mtl is not None and cfg.modes is not None:
        raise CheckpointError("mtl trains on one mode: leave out modes")
    try:
        names = list(decl.mode_list(cfg.mtl, "mtl") if cfg.mtl is not None else decl.mode_list(cfg.modes, "modes"))
    except DeclarationError as e:
        raise CheckpointError(f"the {decl.name} world: {e}") from None
    if cfg.mtl is not None and len(names) != 1:
        raise CheckpointError(f"mtl trains the MTL net of one mode, got {cfg.mtl!r}")
    return names


def resolve(cfg, log=print) -> MultiNetRun:
    """The run's settings from the TrainConfig; the data read (and cached) and split."""
    roots = [r for r in str(cfg.data).split(",") if r]
    _, decl, labels = open_data(type(cfg)(**{**{f.name: getattr(cfg, f.name) for f in fields(cfg)},
                                             "data": roots[0]}))
    names = run_modes(cfg, decl)
    defaults = family(cfg.model).defaults
    options: dict[str, Any] = {"modal": not cfg.mtl, "modes_trained": names} | ({"mtl": cfg.mtl} if cfg.mtl else {})
    spec = make_spec(cfg.model, decl, labels, **options)
    device = resolve_device(cfg.device)
    moments = Moments(roots, (spec["input"]["height"], spec["input"]["width"]), labels, log)
    add_renderers(spec, moments.renderers)
    train_ids, held = moments.split([decl.modes.index(m) for m in names], cfg.seed)
    amp = bool(cfg.amp) and bf16_native(device)
    if cfg.amp and not amp:
        log(f"bfloat16 is not native on this {device.type} (no AVX512-BF16 or AMX): training in float32, which is "
            "faster here")
    return MultiNetRun(roots, Path(cfg.out), names, cfg.mtl,
                       int(math.ceil(cfg.epochs)) if cfg.epochs is not None else int(defaults.get("epochs", 24)),
                       cfg.trials, cfg.batch_size or int(defaults.get("batch_size", 120)), cfg.mode_moments,
                       cfg.lr if cfg.lr is not None else 1.0, cfg.optimizer or "adadelta", cfg.seed, device, amp,
                       cfg.init, spec, moments, train_ids, held, {f.name: getattr(cfg, f.name) for f in fields(cfg)},
                       cfg.steer_share, steering_moments(moments, train_ids, spec["outputs"]))


# --- the steps of the loop ---------------------------------------------------------------------------------------
def make_optimizer(name: str, model: torch.nn.Module, lr: float) -> torch.optim.Optimizer:
    try:
        return optimizer(name, (p for p in model.parameters() if p.requires_grad), lr)
    except ValueError as e:
        raise CheckpointError(str(e)) from None


def new_network(run: MultiNetRun, trial: int) -> tuple[Regressor, torch.optim.Optimizer]:
    """A freshly initialised network for a trial (seeded by the trial), or the weights of `init` (fine-tuning)."""
    torch.manual_seed(run.seed + 1000 * trial)
    model = Regressor(run.spec)
    if run.init:
        start = load_checkpoint(run.init, model="z2color", world=run.moments.decl.name)
        if start["spec"]["options"].get("modal", True) != run.spec["options"]["modal"]:
            raise CheckpointError(f"{run.init} is not a network of the same kind (MultiNet / MTL)")
        model.load_state_dict(start["state_dict"])
        add_renderers(run.spec, start["spec"]["input"].get("renderers", ()))   # it learned those frames too
    model = model.to(run.device).to(memory_format=torch.channels_last).train()
    return model, make_optimizer(run.optimizer, model, run.lr)


def prefetch(items: Iterable, fn, depth: int = 2) -> Iterator:
    """fn(item) for every item, computed one or two ahead in a second thread (batch assembly overlaps training)."""
    q: queue.Queue = queue.Queue(depth)
    done = object()
    stop = threading.Event()

    def work() -> None:
        try:
            for item in items:
                if stop.is_set():
                    return
                q.put(fn(item))
            q.put(done)
        except BaseException as e:   # handed to the consumer, which raises it
            q.put(e)

    thread = threading.Thread(target=work, daemon=True)
    thread.start()
    try:
        while (got := q.get()) is not done:
            if isinstance(got, BaseException):
                raise got
            yield got
    finally:
        stop.set()
        while thread.is_alive():     # unblock a producer waiting on a full queue
            try:
                q.get_nowait()
            except queue.Empty:
                thread.join(0.05)


def scaled_images(model: Regressor, moments: Moments, ids: np.ndarray, device: torch.device,
                  dtype: torch.dtype) -> torch.Tensor:
    """The moments' images as the network reads them, in `dtype` on `device`: on the CPU looked up in the pixel
    table as they are gathered (one pass), else scale_input then the cast (the same values)."""
    table = model.pixel_table(dtype) if device.type == "cpu" and tuple(moments.size) == model.size else None
    if table is not None:
        return torch.from_numpy(moments.looked_up(ids, table)).view(dtype).permute(0, 3, 1, 2)
    pixels = torch.from_numpy(moments.images(ids)).permute(0, 3, 1, 2)
    return model.scale_input(pixels.to(device, non_blocking=True)).to(dtype)


def inputs(run: MultiNetRun, model: Regressor, ids: np.ndarray):
    """A batch as the network reads it: scaled images (channels-last; bfloat16 under autocast), modes, normalised
    targets, all on the run's device."""
    x = scaled_images(model, run.moments, ids, run.device, torch.bfloat16 if run.amp else torch.float32)
    m, y = run.moments.labels(ids)
    target = torch.from_numpy(run.moments.decl.normalise(y.numpy(), model.outputs))
    return x, m.to(run.device), target.to(run.device)


def train_epoch(run: MultiNetRun, model: Regressor, opt: torch.optim.Optimizer, trial: int, epoch: int) -> dict:
    """One pass of balanced batches over the training moments; the mean training loss and the moments/s."""
    rng = np.random.default_rng([run.seed, trial, epoch])
    autocast = torch.autocast(run.device.type, dtype=torch.bfloat16) if run.amp else nullcontext()
    losses, t0 = [], time.perf_counter()
    for x, m, target in prefetch(balanced_batches(run.train_ids, run.batch, rng, run.steps, run.steering,
                                                  run.steer_share),
                                 lambda ids: inputs(run, model, ids)):
        check_signals()
        with autocast:
            pred = model.net(x, m)
        loss = train_loss(pred, target)
        if not torch.isfinite(loss):
            raise CheckpointError(f"the loss diverged ({loss.item()}) in epoch {epoch}; lower --lr")
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), CLIP)
        opt.step()
        losses.append(loss.item())
    return {"trial": trial + 1, "epoch": epoch, "train_loss": float(np.mean(losses)),
            "moments_per_s": round(len(losses) * run.batch / max(time.perf_counter() - t0, 1e-9), 1)}


@torch.no_grad()
def evaluate_loss(model: Regressor, moments: Moments, ids: np.ndarray, device, batch: int = 200,
                  amp: bool = False) -> dict:
    """Mean validation loss (equation 2) over `ids`, overall and per mode, in float32; with `amp` the forward pass
    runs under bfloat16 autocast as training's does (0.2 % from float32's loss, and 1.7x faster here: a tenth of
    an epoch's time)."""
    was_training = model.training
    model.eval()
    losses, modes = [], []
    dtype = torch.bfloat16 if amp else torch.float32
    autocast = torch.autocast(device.type, dtype=torch.bfloat16) if amp else nullcontext()
    for i in range(0, len(ids), batch):
        x = scaled_images(model, moments, ids[i:i + batch], device, dtype)
        m, y = moments.labels(ids[i:i + batch])
        with autocast:
            pred = model.net(x, m.to(device)).float().cpu()
        losses.append(validation_loss(pred, torch.from_numpy(moments.decl.normalise(y.numpy(), model.outputs))))
        modes.append(m)
    model.train(was_training)
    loss, mode = torch.cat(losses), torch.cat(modes)
    out = {"val_loss": float(loss.mean())}
    for k, name in enumerate(moments.decl.modes):
        if (mode == k).any():
            out[f"val_loss_{name}"] = float(loss[mode == k].mean())
    return out


def save_state(run: MultiNetRun, progress: Progress, model: Regressor, opt: torch.optim.Optimizer) -> None:
    save_checkpoint(run.state_path, {"spec": run.spec, "state_dict": model.state_dict(), "optimizer": opt.state_dict(),
                                     "train": {"state": asdict(progress), "config": run.config},
                                     "data": {"roots": run.roots}})


def save_best(run: MultiNetRun, progress: Progress, best_weights: dict | None, finished: bool = False) -> None:
    """The checkpoint (the best network so far and the whole history) and the curves beside it."""
    summary = curves(progress.history, run.names)
    record = {"history": progress.history, "summary": summary, "best": progress.best, "trials": run.trials,
              "epochs": run.epochs, "config": run.config, "finished": finished, "seconds": progress.seconds,
              "amp": run.amp, "moments": {"train": int(sum(len(v) for v in run.train_ids.values())),
                                          "validation": int(len(run.held))}}
    save_checkpoint(run.out, {"spec": run.spec, "state_dict": best_weights, "train": record,
                              "data": {"roots": [str(Path(r).resolve()) for r in run.roots]}})
    rows = [{k.removesuffix("_mean"): v for k, v in r.items()} for r in summary]   # train_loss, val_loss: means
    n = max((r["trials"] for r in summary), default=1)
    write_curves(run.out, rows, x="epoch", title=f"{run.title}: mean over {n} trial(s)"
                 + (", 95 % confidence half-widths in the CSV" if n > 1 else ""))


def curves(history: list[dict], modes: list[str]) -> list[dict]:
    """Per epoch, the mean over trials and the 95 % half-width of the training and validation losses."""
    return summarise_trials(history, ["train_loss", "val_loss"] + [f"val_loss_{m}" for m in modes])


def resume(run: MultiNetRun, log=print):
    """(progress, model, optimiser, best weights) to continue from: a saved state, or a fresh start."""
    if not run.state_path.exists():
        return Progress(), None, None, None
    saved = load_checkpoint(run.state_path, model="z2color", world=run.moments.decl.name)
    config = saved["train"]["config"]
    if config.get("mtl") != run.mtl or config.get("modes") != run.config.get("modes"):
        raise CheckpointError(f"{run.state_path} belongs to another run (other mtl / modes); use another --out")
    progress = Progress(**saved["train"]["state"])
    model = opt = None
    if progress.trial < run.trials:
        model, opt = new_network(run, progress.trial)
        model.load_state_dict(saved["state_dict"])
        opt.load_state_dict(saved["optimizer"])
    best = load_checkpoint(run.out)["state_dict"] if progress.best is not None and run.out.exists() else None
    log(f"continuing {run.title}: trial {progress.trial + 1} of {run.trials}, epoch {progress.epoch} of {run.epochs}")
    return progress, model, opt, best


# --- the trainer --------------------------------------------------------------------------------------------------
class MultiNetTrainer:
    """Z2Color's trainer (perception/trainer.py's protocol): MultiNet, or the MTL net of one mode, for `epochs`
    epochs of each of `trials` trials. A step is one epoch of one trial, validated and saved when it ends."""

    repeats: ClassVar[bool] = True
    reads: ClassVar[frozenset[str]] = frozenset({
        "epochs", "batch_size", "lr", "optimizer", "amp", "modes", "mtl", "trials", "mode_moments", "steer_share",
        "init"})

    def __init__(self, cfg, log=print):
        self.cfg, self.log = cfg, log
        self.model: Regressor | None = None
        self.opt: torch.optim.Optimizer | None = None
        self.best: dict | None = None            # the weights of the best epoch so far
        self.row: dict = {}                      # the epoch just trained
        self.t_start = time.perf_counter()

    def plan(self) -> Plan:
        """The run resolved (its data read and cached, and split); nothing to do when `out` is a finished network
        of the same kind."""
        cfg = self.cfg
        done = None
        if Path(cfg.out).exists() and not Path(str(cfg.out) + ".state").exists():
            done = load_checkpoint(cfg.out, model=cfg.model)
            if done["spec"]["options"].get("mtl") != cfg.mtl:   # an MTL net is not MultiNet, nor another mode's net
                was = done["spec"]["options"].get("mtl")
                raise CheckpointError(f"{cfg.out} is a finished {'MTL net of mode ' + was if was else 'MultiNet'}, "
                                      f"not {'the MTL net of mode ' + cfg.mtl if cfg.mtl else 'MultiNet'}; use "
                                      "another --out")
        first = next((r for r in str(cfg.data).split(",") if r), cfg.data)
        run_modes(cfg, open_data(replace(cfg, data=first))[1])   # before anything is read or written
        if done is not None:
            self.log(f"{cfg.out} is trained already ({done['train'].get('trials', 1)} trial(s)): nothing to do "
                     "(remove it, or give another --out, to train again)")
            return Plan(done=done["train"])
        self.run = resolve(cfg, self.log)
        return Plan(steps=self.run.trials * self.run.epochs, validate_every=1)

    def restore(self) -> Iterator[tuple[int, tuple[int, int]]]:
        """The saved state of an unfinished run, if any; the epochs still to train, as (trial, epoch)."""
        run = self.run
        self.progress, self.model, self.opt, self.best = resume(run, self.log)
        self.log(run.describe())
        self.t_start = time.perf_counter() - self.progress.seconds
        first_trial, epochs_done = self.progress.trial, self.progress.epoch
        return ((trial * run.epochs + epoch, (trial, epoch)) for trial in range(first_trial, run.trials)
                for epoch in range(epochs_done + 1 if trial == first_trial else 1, run.epochs + 1))

    def step(self, work: tuple[int, int]) -> bool:
        """One epoch of balanced batches (work: the trial and the epoch, from 1); a trial starts a fresh network."""
        trial, epoch = work
        if trial != self.progress.trial:
            self.progress.trial, self.progress.epoch, self.model, self.opt = trial, 0, None, None
        if self.model is None or self.opt is None:
            self.model, self.opt = new_network(self.run, trial)
        self.row = train_epoch(self.run, self.model, self.opt, trial, epoch)
        return False   # it saves after every epoch

    def validate(self) -> None:
        """The held-out loss of the epoch into the history; the best network so far kept."""
        run, progress, model = self.run, self.progress, self.model
        assert model is not None   # step() trained it
        row = self.row | evaluate_loss(model, run.moments, run.held, run.device, amp=run.amp)
        progress.history.append(row)
        progress.epoch, progress.seconds = row["epoch"], time.perf_counter() - self.t_start
        if progress.best is None or row["val_loss"] < progress.best["val_loss"]:
            progress.best = {"trial": row["trial"], "epoch": row["epoch"], "val_loss": row["val_loss"]}
            self.best = {k: v.detach().cpu().clone() for k, v in model.state_dict().items()}
        print(f"{run.title}, trial {row['trial']}/{run.trials}, epoch {row['epoch']}/{run.epochs}: train "
              f"loss {row['train_loss']:.5f}, validation loss {row['val_loss']:.5f} "
              f"({row['moments_per_s']:.0f} moments/s)", file=sys.stderr, flush=True)

    def save(self, occasion: Occasion) -> dict:
        """After an epoch: the run's state and the best network; at the end, the best network alone (the state
        goes); on an interruption nothing, since the state of the last whole epoch is saved already."""
        run, progress = self.run, self.progress
        if occasion == "interrupt":
            self.log(f"interrupted: {run.state_path} holds the run after trial {progress.trial + 1}, epoch "
                     f"{progress.epoch}; run the same command to continue")
        elif occasion != "end":
            assert self.model is not None and self.opt is not None   # step() trained them
            save_state(run, progress, self.model, self.opt)
            save_best(run, progress, self.best)
        else:
            progress.seconds = time.perf_counter() - self.t_start
            save_best(run, progress, self.best, finished=True)
            run.state_path.unlink(missing_ok=True)
            b = progress.best or {}
            self.log(f"saved {run.out}: the network of trial {b.get('trial')}, epoch {b.get('epoch')} (validation "
                     f"loss {b.get('val_loss', math.nan):.5f}); curves in {run.out}.loss.csv and .loss.png")
        return {"history": progress.history, "best": progress.best, "finished": occasion == "end"}
