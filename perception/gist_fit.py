"""Fitting the GIST baseline (Liu and Wang, Table 3): descriptors of every training frame, one closed-form ridge
solve per strength, the strength chosen on the validation split; the trainer of the family "gist"."""
from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Iterator
from dataclasses import fields
from pathlib import Path
from typing import ClassVar

import torch
from tqdm import tqdm

from core.signals import check as check_signals
from perception.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from perception.curves import curve_paths, write_curves
from perception.datasets import FrameStream
from perception.gist import GistRegressor
from perception.models import Regressor, add_renderers, describe, make_spec
from perception.shards import DatasetError
from perception.trainer import Occasion, Plan
from perception.training import TrainConfig, data_summary, load_frames, open_data


@torch.no_grad()
def gist_descriptors(model: Regressor, root, split: str, labels, batch: int = 32, limit: int | None = None,
                     desc: str = "") -> tuple[torch.Tensor, torch.Tensor]:
    """GIST descriptors and normalised targets of a split (every frame, or `limit` spread over it)."""
    if limit is not None:
        images, modes, targets = load_frames(root, split, labels, limit)
        chunks: Iterable[tuple[torch.Tensor, torch.Tensor, torch.Tensor]] = [
            (images[i:i + batch], modes[i:i + batch], targets[i:i + batch]) for i in range(0, len(images), batch)]
        total = len(images)
    else:
        stream = FrameStream(root, split, labels, shuffle=False)
        chunks = torch.utils.data.DataLoader(stream, batch_size=batch, num_workers=0)
        total = len(stream)
    feats, targets = [], []
    with tqdm(total=total, unit="frame", desc=desc, file=sys.stderr, dynamic_ncols=True,
              mininterval=1.0 if sys.stderr.isatty() else 30.0) as bar:
        for x, _, y in chunks:
            check_signals()   # a long pass: SIGTERM ends it (the driver's exit_on_sigterm only notes the signal)
            feats.append(_gist(model).descriptor(x.float() / 255.0))
            targets.append(y)
            bar.update(len(x))
    return torch.cat(feats), torch.cat(targets)


def _gist(model: Regressor) -> GistRegressor:
    net = model.net
    assert isinstance(net, GistRegressor)   # a "gist" spec builds one
    return net


class GistTrainer:
    """GIST + ridge (perception/trainer.py's protocol): its one step is the closed-form fit, descriptors of every
    training frame and one solve per ridge strength; validation is the strength the validation split chose (or
    10% of the training frames when there is none)."""

    repeats: ClassVar[bool] = False
    reads: ClassVar[frozenset[str]] = frozenset({"regressor", "val_frames"})

    def __init__(self, cfg: TrainConfig, log=print):
        self.cfg, self.log = cfg, log
        self.out = Path(cfg.out)
        self.sweep: list[dict] = []
        self.record: dict = {}
        self.t0 = time.perf_counter()

    def plan(self) -> Plan:
        """One step; nothing to do when `out` holds a fitted model already."""
        cfg, out = self.cfg, self.out
        self.data, decl, self.labels = open_data(cfg)
        if out.exists():
            ckpt = load_checkpoint(out, model="gist", labels=self.labels, world=decl.name)
            if ckpt["spec"]["options"].get("regressor") != cfg.regressor:
                raise CheckpointError(f"{out} holds GIST + {ckpt['spec']['options'].get('regressor')}, not + "
                                      f"{cfg.regressor}; use another --out")
            self.log(f"{out} is a fitted GIST model already: nothing to do (remove it to fit again)")
            return Plan(done=ckpt["train"])
        if not self.data.frames("train"):
            raise DatasetError(f"dataset {cfg.data} has no frames in split 'train'")
        self.spec = add_renderers(make_spec("gist", decl, self.labels, regressor=cfg.regressor, seed=cfg.seed),
                                  self.data.renderers)
        self.model = Regressor(self.spec).eval()
        return Plan(steps=1)

    def restore(self) -> Iterator[tuple[int, None]]:
        """A fit is not continued: it is done or not."""
        self.t0 = time.perf_counter()
        self.log(f"fitting {describe(self.spec)} on {self.data.frames('train')} frames of {self.cfg.data}")
        return iter([(1, None)])

    def step(self, work: None) -> bool:
        """Descriptors of the training and validation frames, then the sweep of ridge strengths."""
        cfg, data, labels, model = self.cfg, self.data, self.labels, self.model
        feats, targets = gist_descriptors(model, cfg.data, "train", labels, desc="GIST train")
        if data.frames("val"):
            val_feats, val_targets = gist_descriptors(model, cfg.data, "val", labels, limit=cfg.val_frames * 2,
                                                      desc="GIST val")
        else:
            self.log(f"note: {cfg.data} has no validation split; choosing the ridge strength on 10% of the "
                     "training frames")
            held = torch.arange(len(feats)) % 10 == 9
            val_feats, val_targets, feats, targets = feats[held], targets[held], feats[~held], targets[~held]
        self.sweep = _gist(model).fit(feats, targets, val_feats, val_targets)
        return False

    def validate(self) -> None:
        """The ridge strength of the lowest validation loss (the fit keeps its weights)."""
        best = min(self.sweep, key=lambda r: r["val_loss"])
        seconds = time.perf_counter() - self.t0
        self.log(f"ridge strength {best['alpha']:g}: train loss {best['train_loss']:.4f}, val loss "
                 f"{best['val_loss']:.4f} ({seconds:.0f} s)")
        config = {f.name: getattr(self.cfg, f.name) for f in fields(self.cfg)}
        self.record = {"iteration": 0, "epoch": 1, "step_in_epoch": 0, "history": self.sweep, "seconds": seconds,
                       "config": config, "device": "cpu", "finished": True, "alpha": best["alpha"]}

    def save(self, occasion: Occasion) -> dict:
        """The fitted model at the end; an interrupted fit leaves nothing."""
        if occasion != "end":
            return self.record
        out = self.out
        save_checkpoint(out, {"spec": self.spec, "state_dict": self.model.state_dict(), "train": self.record,
                              "data": data_summary(self.data)})
        write_curves(out, self.sweep, x="alpha", title=f"{describe(self.spec)} on {self.data.root.name}: ridge "
                     "strength sweep")
        self.log(f"saved {out}; ridge sweep in {', '.join(str(p) for p in curve_paths(out))}")
        return self.record
