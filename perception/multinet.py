"""Training of Z2Color as MultiNet and as its MTL baselines (Chowdhuri, Pankaj and Zipser, MultiNet: Multi-Modal
Multi-Task Learning for Autonomous Driving, 2017), with the paper's measures.

- Data: data moments (perception/datasets.py) of one or more datasets of the same world, their images averaged 2x2
  to the network's 94 x 168 once and kept in memory (each step's images once; a moment is an index).
- Held-out data: 10 % of the episodes of each behavioural mode (at least one), whole episodes, with every mode
  equally represented (the larger modes' held-out moments are subsampled to the smallest's count).
- Training: Adadelta; the loss over all 20 outputs, 1/(2n) sum_t (s'_t - s_t)^2 + (m'_t - m_t)^2 with n = 10 (the
  paper's equation 1); the gradient norm clipped at 1.0; batches with the modes equally represented.
- Validation: the loss on the last step only, 1/2 ((s'_10 - s_10)^2 + (m'_10 - m_10)^2) (equation 2), per epoch,
  over all held-out moments and per mode.
- Trials: `trials` repeats with fresh seeds (initialisation and shuffling); the curves (CSV and PNG) show the mean
  over trials with 95 % confidence intervals (Student's t). The saved model is the one at the epoch and trial with
  the lowest validation loss, as the paper chose its cars' networks.
- MultiNet trains on every mode with the modal input; an MTL net (`mtl=MODE`) is the same network without the modal
  input, trained and validated on one mode's data.
- Targets must be the expert's: where the world records an operation mode (the sidewalk's `operation`), a moment
  whose future steps include an autonomous one (the network's own command, recorded during an autonomy run) is
  left out; the expert's corrections stay in (the paper's DAgger variant).

A run is resumable at epoch granularity: its state is saved beside the model (`<out>.state`) after every epoch and
on Ctrl-C or SIGTERM; the same command continues it.
"""
from __future__ import annotations

import csv
import io
import math
import sys
import time
from dataclasses import fields
from pathlib import Path

import numpy as np
import torch

from core.files import atomic_write
from core.signals import Terminated, exit_on_sigterm
from core.signals import check as check_signals
from perception.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from perception.datasets import SampleSpec
from perception.models import Regressor, family, make_spec
from perception.shards import Dataset, DatasetError, decode_image, image_column

VALIDATION_SHARE = 0.10
CLIP = 1.0                 # gradient norm (the authors' code)
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262, 10: 2.228,
       15: 2.131, 20: 2.086, 30: 2.042}   # Student's t, two-sided 95 %, by degrees of freedom


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
    keys = sorted(T95)
    return T95[max(k for k in keys if k <= dof)]


class Moments:
    """Every data moment of some datasets of one world, images downsampled once and held in memory."""

    def __init__(self, roots, size: tuple[int, int], targets=None, log=print):
        datasets = [Dataset(Path(r)) for r in roots]
        decl = datasets[0].declaration
        for ds in datasets[1:]:
            if ds.world != decl.name:
                raise DatasetError(f"{ds.root} is a {ds.world} dataset, not a {decl.name} one: datasets trained "
                                   "together must be of one world")
        self.decl = decl
        self.spec = SampleSpec(decl, targets, normalised=False)
        if not decl.modes:
            raise DatasetError(f"the {decl.name} world has no behavioural modes: train another model family")
        self.size = size
        steps, modes, targets_, starts, episodes, t_index = [], [], [], [], [], []
        cams = [image_column(c.name) for c in decl.cameras]
        base = 0
        t0 = time.perf_counter()
        for ds in datasets:
            for shard in ds.shards:
                reader = ds.reader(shard)
                table = reader.labels(self.spec.columns)
                values = np.stack([table.column(n).to_numpy(zero_copy_only=False).astype(np.float64)
                                   for n in self.spec.targets], axis=1)
                mode = table.column(decl.mode_field).to_numpy().astype(np.int64)
                by_expert = np.ones(len(values), dtype=bool)
                if "operation" in decl.truth_names:   # 1: autonomous, a network's command, never a label
                    by_expert = reader.labels(["operation"]).column("operation").to_numpy() != 1
                images = []
                for group in reader.iter_row_groups(cams):
                    cols = [group.column(c).to_pylist() for c in cams]
                    for row in zip(*cols):
                        images.append([self._small(decode_image(b)) for b in row])
                steps.append(np.asarray(images, dtype=np.uint8))       # (steps, cameras, h, w, 3)
                horizon = self.spec.moment.horizon
                for t in self.spec.starts(len(values)):
                    if not by_expert[t + 1:t + 1 + horizon].all():
                        continue
                    starts.append(base + t)
                    t_index.append(len(steps) - 1)
                    modes.append(mode[t])
                    targets_.append(self.spec.target_values(values, t))
                    episodes.append((str(ds.root), shard.episode))
                base += len(values)
        if not starts:
            raise DatasetError("the datasets hold no complete data moment")
        self.images = np.concatenate(steps)                                # every step's images, once
        self.index = np.asarray(starts)                                    # step of each moment
        self.modes = np.asarray(modes)
        self.targets = np.asarray(targets_, dtype=np.float32)
        self.episodes = episodes
        self.instants = np.asarray(self.spec.moment.instants)
        log(f"read {len(self.index)} data moments of {len(roots)} dataset(s) ({self.images.nbytes / 1e6:.0f} MB of "
            f"images at {size[1]}x{size[0]}) in {time.perf_counter() - t0:.0f} s")

    def _small(self, rgb: np.ndarray) -> np.ndarray:
        import cv2
        h, w = self.size
        return rgb if rgb.shape[:2] == (h, w) else cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA)

    def batch(self, ids) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(uint8 images (B, instants * cameras * 3, h, w), modes (B,), raw targets (B, outputs))."""
        steps = self.index[ids][:, None] + self.instants[None, :]          # (B, instants)
        imgs = self.images[steps]                                           # (B, instants, cams, h, w, 3)
        b, i, c, h, w, _ = imgs.shape
        x = imgs.transpose(0, 1, 2, 5, 3, 4).reshape(b, i * c * 3, h, w)
        return (torch.from_numpy(np.ascontiguousarray(x)), torch.from_numpy(self.modes[ids]),
                torch.from_numpy(self.targets[ids]))

    def split(self, modes: list[int], seed: int = 0) -> tuple[dict, np.ndarray]:
        """({mode: training moment ids}, held-out ids): 10 % of each mode's episodes (at least one) held out
        whole, and the held-out moments subsampled so that every mode has as many."""
        rng = np.random.default_rng([seed, 0x5A1])
        train, held = {}, {}
        for m in modes:
            ids = np.flatnonzero(self.modes == m)
            if not len(ids):
                raise DatasetError(f"the data hold no moment of mode {self.decl.modes[m]}")
            eps = sorted({self.episodes[i] for i in ids})
            if len(eps) < 2:
                raise DatasetError(f"mode {self.decl.modes[m]} has {len(eps)} episode(s): at least 2 are needed to "
                                   "hold one out for validation")
            k = max(1, int(round(VALIDATION_SHARE * len(eps))))
            out = {eps[j] for j in rng.choice(len(eps), k, replace=False)}
            is_held = np.array([self.episodes[i] in out for i in ids])
            train[m], held[m] = ids[~is_held], ids[is_held]
        n = min(len(v) for v in held.values())
        held_ids = np.concatenate([np.sort(rng.choice(v, n, replace=False)) for v in held.values()])
        return train, held_ids


def balanced_batches(train: dict, batch: int, rng: np.random.Generator, batches: int):
    """`batches` batches of `batch` moments, each mode an equal share (each mode's pool shuffled and cycled)."""
    modes = sorted(train)
    per = max(1, batch // len(modes))
    pools = {m: rng.permutation(train[m]) for m in modes}
    pos = {m: 0 for m in modes}
    for _ in range(batches):
        ids = []
        for m in modes:
            if pos[m] + per > len(pools[m]):
                pools[m], pos[m] = rng.permutation(train[m]), 0
            take = pools[m][pos[m]:pos[m] + per]
            if len(take) < per:   # a pool smaller than its share: draw with replacement
                take = rng.choice(train[m], per, replace=True)
            ids.append(take)
            pos[m] += per
        yield np.concatenate(ids)


@torch.no_grad()
def evaluate_loss(model: Regressor, moments: Moments, ids: np.ndarray, device, batch: int = 200) -> dict:
    """Mean validation loss (equation 2) over `ids`, overall and per mode."""
    model.eval()
    losses, modes = [], []
    for i in range(0, len(ids), batch):
        x, m, y = moments.batch(ids[i:i + batch])
        pred = model(x.to(device), m.to(device)).float().cpu()
        target = torch.from_numpy(moments.decl.normalise(y.numpy(), model.outputs))
        losses.append(validation_loss(pred, target))
        modes.append(m)
    model.train()
    loss, mode = torch.cat(losses), torch.cat(modes)
    out = {"val_loss": float(loss.mean())}
    for k, name in enumerate(moments.decl.modes):
        sel = mode == k
        if sel.any():
            out[f"val_loss_{name}"] = float(loss[sel].mean())
    return out


def summarise_trials(history: list[dict], keys) -> list[dict]:
    """Per epoch: the mean over trials and its 95 % confidence half-width of each key."""
    epochs = sorted({r["epoch"] for r in history})
    out = []
    for e in epochs:
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


def curve_paths(out) -> tuple[Path, Path, Path]:
    out = Path(out)
    return (out.with_name(out.name + ".curves.csv"), out.with_name(out.name + ".trials.csv"),
            out.with_name(out.name + ".curves.png"))


def _csv(rows: list[dict]) -> bytes:
    cols = list(dict.fromkeys(k for r in rows for k in r))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols, lineterminator="\n")
    w.writeheader()
    w.writerows({k: ("" if r.get(k) is None else r[k]) for k in cols} for r in rows)
    return buf.getvalue().encode()


def write_curves(out, history: list[dict], modes: list[str], title: str) -> None:
    """The per-epoch validation curves: mean over trials with 95 % confidence bands, overall and per mode."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = ["train_loss", "val_loss"] + [f"val_loss_{m}" for m in modes]
    summary = summarise_trials(history, keys)
    curves, trials, png = curve_paths(out)
    atomic_write(curves, _csv(summary))
    atomic_write(trials, _csv(history))
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=100)
    x = [r["epoch"] for r in summary]
    for key, style in [("val_loss", "o-")] + [(f"val_loss_{m}", "--") for m in modes if len(modes) > 1]:
        mean = np.array([r.get(f"{key}_mean", np.nan) for r in summary])
        ci = np.array([r.get(f"{key}_ci95") or 0.0 for r in summary])
        line, = ax.plot(x, mean, style, markersize=3, label=key.replace("val_loss_", "validation, ")
                        .replace("val_loss", "validation (all modes)"))
        ax.fill_between(x, mean - ci, mean + ci, color=line.get_color(), alpha=0.2)
    ax.set_xlabel("epoch")
    ax.set_ylabel("validation loss (last step, eq. 2)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    n = max((r["trials"] for r in summary), default=1)
    ax.set_title(f"{title}: mean over {n} trial(s)" + (", 95 % CI" if n > 1 else ""), fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    atomic_write(png, buf.getvalue())


def train_multinet(cfg, log=print) -> dict:
    """Train Z2Color (MultiNet, or MTL on one mode) on cfg.data for cfg.epochs epochs x cfg.trials trials."""
    from perception.training import open_data, resolve_device

    roots = [r for r in str(cfg.data).split(",") if r]
    cfg_data = roots[0]
    data, decl, labels = open_data(type(cfg)(**{**{f.name: getattr(cfg, f.name) for f in fields(cfg)},
                                               "data": cfg_data}))
    fam = family(cfg.model)
    if cfg.mtl and cfg.modes:
        raise CheckpointError("--mtl MODE trains on one mode: leave out --modes")
    names = [cfg.mtl] if cfg.mtl else [m.strip() for m in (cfg.modes or ",".join(decl.modes)).split(",") if m.strip()]
    unknown = [m for m in names if m not in decl.modes]
    if unknown:
        raise CheckpointError(f"the {decl.name} world has no behavioural mode {', '.join(unknown)} "
                              f"(modes: {', '.join(decl.modes)})")
    modes = [decl.modes.index(m) for m in names]
    device = resolve_device(cfg.device)
    defaults = fam.defaults
    epochs = int(math.ceil(cfg.epochs)) if cfg.epochs is not None else int(defaults.get("epochs", 24))
    batch = cfg.batch_size or int(defaults.get("batch_size", 120))
    lr = cfg.lr if cfg.lr is not None else 1.0
    optimizer = cfg.optimizer or "adadelta"
    out = Path(cfg.out)
    state_path = out.with_name(out.name + ".state")
    options = {"modal": not cfg.mtl, "modes_trained": names}
    if cfg.mtl:
        options["mtl"] = cfg.mtl
    spec = make_spec(cfg.model, decl, labels, **options)
    moments = Moments(roots, (spec["input"]["height"], spec["input"]["width"]), labels, log)
    train_ids, held = moments.split(modes, cfg.seed)
    n_train = sum(len(v) for v in train_ids.values())
    steps = max(1, n_train // batch)
    title = f"{'MTL ' + cfg.mtl if cfg.mtl else 'MultiNet'} on {', '.join(names)}"

    state = {"trial": 0, "epoch": 0, "history": [], "best": None, "seconds": 0.0}
    model = opt = None
    if state_path.exists():
        saved = load_checkpoint(state_path, model=cfg.model, world=decl.name)
        if saved["train"]["config"].get("mtl") != cfg.mtl or saved["train"]["config"].get("modes") != cfg.modes:
            raise CheckpointError(f"{state_path} belongs to another run (other --mtl / --modes); use another --out")
        state = saved["train"]["state"]
        if state["trial"] < cfg.trials:
            model = Regressor(saved["spec"]).to(device)
            model.load_state_dict(saved["state_dict"])
            opt = _optimizer(optimizer, model, lr)
            opt.load_state_dict(saved["optimizer"])
        log(f"continuing {title}: trial {state['trial'] + 1} of {cfg.trials}, epoch {state['epoch']} of {epochs}")
    elif out.exists():
        done = load_checkpoint(out, model=cfg.model, world=decl.name)
        log(f"{out} is trained already ({done['train'].get('trials', 1)} trial(s)): nothing to do (remove it, or "
            "give another --out, to train again)")
        return done["train"]

    log(f"training {title}: Z2Color, {sum(p.numel() for p in Regressor(spec).parameters()):,} parameters; "
        f"{n_train} training and {len(held)} held-out moments; {cfg.trials} trial(s) x {epochs} epochs of {steps} "
        f"batches of {batch}, {optimizer} lr {lr:g}, gradient norm clipped at {CLIP} on {device}")
    best_state = None
    if state.get("best") is not None and out.exists():
        best_state = load_checkpoint(out)["state_dict"]

    def save_state() -> None:
        if model is None:
            return
        config = {f.name: getattr(cfg, f.name) for f in fields(cfg)}
        save_checkpoint(state_path, {"spec": spec, "state_dict": model.state_dict(), "optimizer": opt.state_dict(),
                                     "train": {"state": state, "config": config}, "data": {"roots": roots}})

    def save_best(final: bool = False) -> None:
        config = {f.name: getattr(cfg, f.name) for f in fields(cfg)}
        record = {"history": state["history"], "best": state["best"], "trials": cfg.trials, "epochs": epochs,
                  "config": config, "finished": final, "seconds": state["seconds"],
                  "moments": {"train": n_train, "validation": int(len(held))}}
        save_checkpoint(out, {"spec": spec, "state_dict": best_state, "train": record,
                              "data": {"roots": [str(Path(r).resolve()) for r in roots]}})
        write_curves(out, state["history"], names, title)

    t_start = time.perf_counter() - state["seconds"]
    try:
        with exit_on_sigterm(poll=True):
            while state["trial"] < cfg.trials:
                trial = state["trial"]
                if model is None:
                    torch.manual_seed(cfg.seed + 1000 * trial)
                    model = Regressor(spec).to(device).train()
                    if cfg.init:   # fine-tuning: the weights of an earlier network of the same kind
                        start = load_checkpoint(cfg.init, model=cfg.model, world=decl.name)
                        if start["spec"]["options"].get("modal", True) != spec["options"]["modal"]:
                            raise CheckpointError(f"{cfg.init} is not a network of the same kind (MultiNet / MTL)")
                        model.load_state_dict(start["state_dict"])
                    opt = _optimizer(optimizer, model, lr)
                while state["epoch"] < epochs:
                    epoch = state["epoch"] + 1
                    rng = np.random.default_rng([cfg.seed, trial, epoch])
                    losses, t0 = [], time.perf_counter()
                    for ids in balanced_batches(train_ids, batch, rng, steps):
                        check_signals()
                        x, m, y = moments.batch(ids)
                        target = torch.from_numpy(decl.normalise(y.numpy(), model.outputs)).to(device)
                        loss = train_loss(model(x.to(device), m.to(device)), target)
                        if not torch.isfinite(loss):
                            raise CheckpointError(f"the loss diverged ({loss.item()}) in epoch {epoch}; lower --lr")
                        opt.zero_grad(set_to_none=True)
                        loss.backward()
                        torch.nn.utils.clip_grad_norm_(model.parameters(), CLIP)
                        opt.step()
                        losses.append(loss.item())
                    row = {"trial": trial + 1, "epoch": epoch, "train_loss": float(np.mean(losses)),
                           **evaluate_loss(model, moments, held, device),
                           "moments_per_s": round(len(losses) * batch / max(time.perf_counter() - t0, 1e-9), 1)}
                    state["history"].append(row)
                    state["epoch"] = epoch
                    state["seconds"] = time.perf_counter() - t_start
                    if state["best"] is None or row["val_loss"] < state["best"]["val_loss"]:
                        state["best"] = {"trial": trial + 1, "epoch": epoch, "val_loss": row["val_loss"]}
                        best_state = {k: v.detach().cpu().clone() for k, v in model.state_dict().items()}
                    print(f"{title}, trial {trial + 1}/{cfg.trials}, epoch {epoch}/{epochs}: train loss "
                          f"{row['train_loss']:.5f}, validation loss {row['val_loss']:.5f} "
                          f"({row['moments_per_s']:.0f} moments/s)", file=sys.stderr, flush=True)
                    save_state()
                    save_best()
                state["trial"] += 1
                state["epoch"] = 0
                model = opt = None
    except (KeyboardInterrupt, Terminated):
        state["seconds"] = time.perf_counter() - t_start
        save_state()
        log(f"interrupted: saved {state_path} after epoch {state['epoch']}; run the same command to continue")
        raise
    state["seconds"] = time.perf_counter() - t_start
    save_best(final=True)
    state_path.unlink(missing_ok=True)
    b = state["best"]
    log(f"saved {out}: the network of trial {b['trial']}, epoch {b['epoch']} (validation loss {b['val_loss']:.5f}); "
        f"curves in {', '.join(str(p) for p in curve_paths(out))}")
    return {"history": state["history"], "best": b, "finished": True}


def _optimizer(name: str, model, lr: float):
    params = [p for p in model.parameters() if p.requires_grad]
    if name == "adadelta":
        return torch.optim.Adadelta(params, lr=lr)
    if name == "adam":
        return torch.optim.Adam(params, lr=lr)
    if name == "sgd":
        return torch.optim.SGD(params, lr=lr, momentum=0.9)
    raise CheckpointError(f"unknown optimizer '{name}' (adadelta, adam or sgd)")
