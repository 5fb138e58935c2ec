"""Evaluation: mean absolute error per output of models of any world, with inference latency and throughput; for
the highway, in the layout of Liu and Wang's Table 3, split by regime and by lane count.

MAE is in the labels' own units (angle in radians, toMarking_* and dist_* in metres, steering and motor in their
[0, 1] units), over the samples of one split (test by default: whole episodes no model has trained on). Regimes
come from the dataset's `in_lane` / `on_marking` columns where the world records them: in lane only, on marking
only, and the overlap where both systems are active. `evaluate` computes; it writes nothing
(drivestudio/commands/evaluate.py writes the files).
"""
from __future__ import annotations

import csv
import io
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from core.worlds.highway import PAPER_INDICATORS
from perception.checkpoint import CheckpointError, load_model
from perception.datasets import FrameStream
from perception.models import describe
from perception.predictor import Predictor
from perception.shards import Dataset, DatasetError

SHORT = {"angle": "angle", "toMarking_LL": "to_LL", "toMarking_ML": "to_ML", "toMarking_MR": "to_MR",
         "toMarking_RR": "to_RR", "dist_LL": "dist_LL", "dist_MM": "dist_MM", "dist_RR": "dist_RR",
         "toMarking_L": "to_L", "toMarking_M": "to_M", "toMarking_R": "to_R", "dist_L": "dist_L",
         "dist_R": "dist_R", "fast": "fast", "lanes_left": "lanes_left"}
TABLE3 = {  # Liu and Wang, Table 3: MAE on 10,000 held-out TORCS frames, PAPER_INDICATORS order
    "GIST": (0.051, 1.033, 0.596, 0.598, 1.140, 18.561, 13.081, 20.542, 1.201, 1.310, 1.462, 30.164, 30.138),
    "AlexNet": (0.048, 0.221, 0.203, 0.199, 0.223, 11.574, 9.842, 12.319, 0.174, 0.195, 0.178, 10.920, 8.927),
    "VGG-16 (conv frozen)": (0.062, 0.569, 0.466, 0.431, 0.568, 13.526, 10.901, 13.627, 0.577, 0.575, 0.555,
                             14.572, 12.266),
}
REGIMES = {"in lane only": (True, False), "on marking only": (False, True), "overlap (both)": (True, True),
           "neither": (False, False)}
CONTEXT = ("in_lane", "on_marking", "lanes")  # columns read beside the labels


@dataclass
class ModelResult:
    path: str
    spec: dict
    name: str
    errors: np.ndarray        # (samples, outputs) absolute errors in the labels' units
    in_lane: np.ndarray       # per sample; all False where the world has no such column
    on_marking: np.ndarray
    lanes: np.ndarray         # per sample; 0 where the world has no lanes
    timing: dict = field(default_factory=dict)

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(self.spec["outputs"])

    def mae(self, mask=None) -> dict[str, float]:
        e = self.errors if mask is None else self.errors[mask]
        return {n: float(v) for n, v in zip(self.labels, e.mean(0))} if len(e) else {}


@dataclass
class Evaluation:
    results: list[ModelResult]
    data: str
    split: str
    frames: int
    episodes: int
    world: str = "highway"
    markdown: str = ""
    files: dict = field(default_factory=dict)  # file name -> str (text), np.ndarray (RGB image) or dict (JSON)


def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def evaluate_model(path, data: str, split: str = "test", device: str = "cpu", batch_size: int = 32,
                   workers: int = 0, latency_frames: int = 100, log=print) -> ModelResult:
    device = torch.device(device)
    ds = Dataset(Path(data))
    try:
        model, ckpt = load_model(path, device=device, world=ds.world)
    except CheckpointError as e:
        raise CheckpointError(f"{e} (the dataset {data} is of the {ds.world} world)") from None
    spec = ckpt["spec"]
    labels = tuple(spec["labels"])
    context = tuple(c for c in CONTEXT if not ds.has_columns([c]))
    stream = FrameStream(data, split, labels, normalised=False, shuffle=False, context=context)
    loader = torch.utils.data.DataLoader(stream, batch_size=batch_size, num_workers=workers)
    errors, contexts, seconds, first = [], [], 0.0, None
    with torch.inference_mode(), tqdm(total=len(stream), unit="sample", desc=Path(path).name, file=sys.stderr,
                                      dynamic_ncols=True, mininterval=1.0 if sys.stderr.isatty() else 30.0) as bar:
        for batch in loader:
            x, m, y = batch[:3]
            if first is None:
                first = (x[:1].clone(), m[:1].clone())
                model(first[0].to(device), first[1].to(device))  # warm-up, not timed
            _sync(device)
            t0 = time.perf_counter()
            pred = model(x.to(device), m.to(device))
            _sync(device)
            seconds += time.perf_counter() - t0
            errors.append(np.abs(model.denormalise(pred) - y.double().numpy()))
            contexts.append(batch[3].numpy() if context else np.zeros((len(x), 0)))
            bar.update(len(x))
    errors, ctx = np.concatenate(errors), np.concatenate(contexts)
    frames = len(errors)
    column = {c: ctx[:, i] for i, c in enumerate(context)}
    zeros = np.zeros(frames)
    predictor = Predictor(model, spec, device)
    sample = FrameStream(data, split, labels, normalised=False, shuffle=False)
    images = []
    for img, mode, _ in sample:
        chw = img.numpy()
        images.append(([chw[k:k + 3].transpose(1, 2, 0) for k in range(0, chw.shape[0], 3)], int(mode)))
        if len(images) >= min(latency_frames, frames):
            break
    for img, mode in images[:2]:
        predictor(img, mode if mode >= 0 else None)  # warm-up
    lat = []
    for img, mode in images:
        t0 = time.perf_counter()
        predictor(img, mode if mode >= 0 else None)
        lat.append(time.perf_counter() - t0)
    timing = {"frames": frames, "batch_size": batch_size, "throughput_fps": frames / max(seconds, 1e-9),
              "latency_ms_median": float(np.median(lat) * 1e3), "latency_ms_p90": float(np.percentile(lat, 90) * 1e3),
              "latency_frames": len(lat), "device": _device_name(device), "threads": torch.get_num_threads(),
              "parameters": sum(p.numel() for p in model.parameters())
              + sum(b.numel() for b in model.buffers())}
    return ModelResult(str(path), spec, describe(spec), errors, column.get("in_lane", zeros) > 0.5,
                       column.get("on_marking", zeros) > 0.5, column.get("lanes", zeros).round().astype(int),
                       timing)


def _device_name(device: torch.device) -> str:
    if device.type == "cuda":
        return torch.cuda.get_device_name(device)
    import platform
    return f"cpu ({platform.processor() or platform.machine()}, {torch.get_num_threads()} threads)"


def evaluate(data, checkpoints, split: str = "test", device: str = "cpu", batch_size: int = 32,
             workers: int = 0, latency_frames: int = 100, log=print) -> Evaluation:
    """Evaluate each checkpoint on `split` of `data`; the report is in `.markdown` and `.files`."""
    ds = Dataset(Path(data))
    shards = ds.select(split)
    if not shards:
        raise DatasetError(f"dataset {data} has no frames in split '{split}'")
    results = [evaluate_model(p, data, split, device, batch_size, workers, latency_frames, log) for p in checkpoints]
    ev = Evaluation(results, str(data), split, sum(r.timing["frames"] for r in results[:1]), len(shards),
                    world=ds.world)
    names = [r.name for r in results]
    for r in results:  # two checkpoints of one kind are told apart by file name
        if names.count(r.name) > 1:
            r.name = f"{r.name} ({Path(r.path).name})"
    ev.markdown = markdown(ev)
    ev.files = {"mae.md": ev.markdown, "mae.csv": mae_csv(ev), "mae_by_regime.csv": breakdown_csv(ev, "regime"),
                "mae_by_lanes.csv": breakdown_csv(ev, "lanes"), "speed.csv": speed_csv(ev),
                "mae.png": bar_chart(ev), "evaluation.json": summary(ev)}
    return ev


# --- tables -------------------------------------------------------------------------------------------------
def columns(ev: Evaluation) -> list[str]:
    if ev.world != "highway":
        return list(dict.fromkeys(n for r in ev.results for n in r.labels))
    extra = [n for n in ("fast", "lanes_left") if any(n in r.labels for r in ev.results)]
    return list(PAPER_INDICATORS) + extra


def _paper(ev: Evaluation) -> dict:
    """Liu and Wang's rows, for the highway only (the reference of its Table 3 layout)."""
    return TABLE3 if ev.world == "highway" else {}


def _fmt(v) -> str:
    if v is None:
        return "—"
    return f"{v:.3f}" if abs(v) < 100 else f"{v:.1f}"


def _table(rows: list[tuple[str, dict]], cols: list[str], first: str = "model") -> str:
    lines = [f"| {first} | " + " | ".join(SHORT.get(c, c) for c in cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for name, mae in rows:
        lines.append(f"| {name} | " + " | ".join(_fmt(mae.get(c)) for c in cols) + " |")
    return "\n".join(lines)


def masks(ev: Evaluation, r: ModelResult, by: str) -> list[tuple[str, np.ndarray]]:
    if ev.world != "highway":
        return []
    if by == "regime":
        out = [(name, (r.in_lane == a) & (r.on_marking == b)) for name, (a, b) in REGIMES.items()]
        return [(n, m) for n, m in out if m.any() or n != "neither"]
    return [(f"{k} lane{'s' if k != 1 else ''}", r.lanes == k) for k in sorted(set(r.lanes.tolist()))]


def markdown(ev: Evaluation) -> str:
    cols = columns(ev)
    if ev.world == "highway":
        intro = (f"Split `{ev.split}` of `{ev.data}`: {ev.frames} frames in {ev.episodes} episodes. MAE in the "
                 "indicators' units (angle in rad, toMarking_* and dist_* in m), laid out as Liu and Wang's Table 3 "
                 "(Deeper Direct Perception in Autonomous Driving). Their rows were measured on 10,000 TORCS "
                 "frames, not on these: they are a reference, not a like-for-like comparison.")
    else:
        intro = (f"Split `{ev.split}` of `{ev.data}` ({ev.world} world): {ev.frames} samples in {ev.episodes} "
                 "episodes. MAE per output in the labels' units.")
    out = ["# Perception: mean absolute error per output" if ev.world != "highway" else
           "# Perception: mean absolute error per indicator", "", intro, "",
           _table([(r.name, r.mae()) for r in ev.results]
                  + [(f"*paper: {k}*", dict(zip(PAPER_INDICATORS, v))) for k, v in _paper(ev).items()], cols),
           ""]
    for by, title in (("regime", "By regime (dataset columns in_lane / on_marking)"), ("lanes", "By lane count")):
        out += [f"## {title}", ""]
        groups = {}
        for r in ev.results:
            for name, m in masks(ev, r, by):
                groups.setdefault(name, []).append((r, m))
        for name, items in groups.items():
            if not items[0][1].any():
                continue
            out += [f"### {name}: {int(items[0][1].sum())} frames", "",
                    _table([(r.name, r.mae(m)) for r, m in items], cols), ""]
    out += ["## Speed", "",
            "| model | parameters | latency ms/frame (batch 1, median) | latency p90 | throughput frames/s "
            "(batched) | batch | device |", "|---|---|---|---|---|---|---|"]
    for r in ev.results:
        t = r.timing
        out.append(f"| {r.name} | {t['parameters']:,} | {t['latency_ms_median']:.1f} | {t['latency_ms_p90']:.1f} | "
                   f"{t['throughput_fps']:.1f} | {t['batch_size']} | {t['device']} |")
    out.append("")
    return "\n".join(out)


def _csv(header: list[str], rows: list[list]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in rows:
        w.writerow(["" if v is None else (f"{v:.6g}" if isinstance(v, float) else v) for v in row])
    return buf.getvalue()


def mae_csv(ev: Evaluation) -> str:
    cols = columns(ev)
    rows = [["ours", r.name, r.path, len(r.errors)] + [r.mae().get(c) for c in cols] for r in ev.results]
    rows += [["paper", k, "", 10000] + list(v) + [None] * (len(cols) - len(v)) for k, v in _paper(ev).items()]
    return _csv(["source", "model", "checkpoint", "frames"] + cols, rows)


def breakdown_csv(ev: Evaluation, by: str) -> str:
    cols = columns(ev)
    rows = []
    for r in ev.results:
        for name, m in masks(ev, r, by):
            rows.append([r.name, name, int(m.sum())] + [r.mae(m).get(c) for c in cols])
    return _csv(["model", by, "frames"] + cols, rows)


def speed_csv(ev: Evaluation) -> str:
    keys = ["parameters", "latency_ms_median", "latency_ms_p90", "throughput_fps", "batch_size", "device", "threads"]
    return _csv(["model"] + keys, [[r.name] + [r.timing[k] for k in keys] for r in ev.results])


def summary(ev: Evaluation) -> dict:
    return {"data": ev.data, "split": ev.split, "frames": ev.frames, "episodes": ev.episodes,
            "models": [{"name": r.name, "checkpoint": r.path, "spec": r.spec, "mae": r.mae(),
                        "by_regime": {n: {"frames": int(m.sum()), "mae": r.mae(m)} for n, m in masks(ev, r, "regime")},
                        "by_lanes": {n: {"frames": int(m.sum()), "mae": r.mae(m)} for n, m in masks(ev, r, "lanes")},
                        "timing": r.timing} for r in ev.results],
            "world": ev.world,
            "paper_table3": {k: dict(zip(PAPER_INDICATORS, v)) for k, v in _paper(ev).items()}}


def bar_chart(ev: Evaluation) -> np.ndarray:
    """Grouped bars of MAE per indicator, ours solid and the paper's hatched; one panel per unit/scale."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = columns(ev)
    if ev.world == "highway":
        panels = [("angle [rad]", ["angle"]), ("toMarking [m]", [c for c in cols if c.startswith("toMarking")]),
                  ("dist [m]", [c for c in cols if c.startswith("dist")])]
        extra = [c for c in cols if c in ("fast", "lanes_left")]
        if extra:
            panels.append(("extra", extra))
    else:
        groups: dict = {}
        for c in cols:
            groups.setdefault(c.split("+", 1)[0], []).append(c)
        panels = list(groups.items())
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    series = [(r.name, r.mae(), {"color": colors[k % len(colors)]}) for k, r in enumerate(ev.results)]
    series += [(f"paper: {k}", dict(zip(PAPER_INDICATORS, v)), {"hatch": "//", "color": grey, "edgecolor": "0.2"})
               for (k, v), grey in zip(_paper(ev).items(), ("0.45", "0.65", "0.85"))]
    widths = [max(1.6, 0.9 * len(c)) for _, c in panels]
    fig, axes = plt.subplots(1, len(panels), figsize=(sum(widths) + 2, 4.2), dpi=100,
                             gridspec_kw={"width_ratios": widths})
    n = len(series)
    for ax, (title, names) in zip(np.atleast_1d(axes), panels):
        x = np.arange(len(names))
        for k, (label, mae, style) in enumerate(series):
            vals = [mae.get(c, np.nan) for c in names]
            ax.bar(x + (k - (n - 1) / 2) * 0.8 / n, vals, 0.8 / n, label=label, **style)
        ax.set_xticks(x, [SHORT.get(c, c) for c in names], rotation=45 if len(names) > 3 else 0, fontsize=8)
        ax.set_title(title, fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    np.atleast_1d(axes)[0].set_ylabel("MAE")
    handles, labels = np.atleast_1d(axes)[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(n, 4), fontsize=8, frameon=False)
    fig.suptitle(f"MAE per indicator, split {ev.split} ({ev.frames} frames)", fontsize=10)
    fig.tight_layout(rect=(0, 0.12 + 0.04 * ((n - 1) // 4), 1, 0.95))
    fig.canvas.draw()
    rgb = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return rgb
