"""Fitting the GIST baseline (Liu and Wang, Table 3): descriptors of every training frame, one closed-form ridge
solve per strength, the strength chosen on the validation split."""
from __future__ import annotations

import sys
import time
from collections.abc import Iterable
from dataclasses import fields
from pathlib import Path

import torch
from tqdm import tqdm

from perception.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from perception.curves import curve_paths, write_curves
from perception.datasets import FrameStream
from perception.gist import GistRegressor
from perception.models import Regressor, describe, make_spec
from perception.shards import DatasetError
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
            feats.append(_gist(model).descriptor(x.float() / 255.0))
            targets.append(y)
            bar.update(len(x))
    return torch.cat(feats), torch.cat(targets)


def _gist(model: Regressor) -> GistRegressor:
    net = model.net
    assert isinstance(net, GistRegressor)   # a "gist" spec builds one
    return net


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
    sweep = _gist(model).fit(feats, targets, val_feats, val_targets)
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
