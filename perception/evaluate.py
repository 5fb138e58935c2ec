"""Evaluation: mean absolute error per output of models of any world, with inference latency and throughput.

MAE is in the labels' own units (angle in radians, toMarking_* and dist_* in metres, steering and motor in their
[0, 1] units), over the samples of one split (test by default: whole episodes no model has trained on). How the
report is laid out is the world's (a ReportLayout from its plugin): any world gets one column per output; the
highway's (perception/highway/table3.py) is Liu and Wang's Table 3, split by regime and lane count. `evaluate`
computes; it writes nothing (drivestudio/commands/evaluate.py writes the files).
"""
from __future__ import annotations

import csv
import io
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from core.declaration import Moment
from perception.checkpoint import CheckpointError
from perception.datasets import FrameStream
from perception.mae_report import Evaluation, ModelResult, ReportLayout
from perception.models import describe, load_model
from perception.predictor import Predictor
from perception.shards import Dataset, DatasetError

# the files of a report, which the CLI checks can be written before evaluating anything
REPORT_FILES = ("mae.md", "mae.csv", "mae_by_regime.csv", "mae_by_lanes.csv", "speed.csv", "mae.png",
                "evaluation.json")


def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def evaluate_model(path, data: str, split: str = "test", device: str = "cpu", batch_size: int = 32,
                   workers: int = 0, latency_frames: int = 100, log=print,
                   layout: ReportLayout | None = None) -> ModelResult:
    dev = torch.device(device)
    ds = Dataset(Path(data))
    try:
        model, ckpt = load_model(path, device=dev, world=ds.world)
    except CheckpointError as e:
        raise CheckpointError(f"{e} (the dataset {data} is of the {ds.world} world)") from None
    spec = ckpt["spec"]
    labels = tuple(spec["labels"])
    context = tuple(c for c in (layout or ReportLayout()).context if not ds.missing_columns([c]))
    # the frames the model reads: a temporal model (the training setting history) takes earlier steps beside this one
    instants = tuple(spec["input"].get("instants", ds.declaration.moment.instants))
    moment = Moment(instants, ds.declaration.moment.horizon) if instants != ds.declaration.moment.instants else None
    stream = FrameStream(data, split, labels, normalised=False, shuffle=False, context=context, moment=moment)
    loader = torch.utils.data.DataLoader(stream, batch_size=batch_size, num_workers=workers)
    batch_errors: list[np.ndarray] = []
    contexts: list[np.ndarray] = []
    seconds, first = 0.0, None
    with torch.inference_mode(), tqdm(total=len(stream), unit="sample", desc=Path(path).name, file=sys.stderr,
                                      dynamic_ncols=True, mininterval=1.0 if sys.stderr.isatty() else 30.0) as bar:
        for batch in loader:
            x, m, y = batch[:3]
            if first is None:
                first = (x[:1].clone(), m[:1].clone())
                model(first[0].to(dev), first[1].to(dev))  # warm-up, not timed
            _sync(dev)
            t0 = time.perf_counter()
            pred = model(x.to(dev), m.to(dev))
            _sync(dev)
            seconds += time.perf_counter() - t0
            batch_errors.append(np.abs(model.denormalise(pred) - y.double().numpy()))
            contexts.append(batch[3].numpy() if context else np.zeros((len(x), 0)))
            bar.update(len(x))
    errors, ctx = np.concatenate(batch_errors), np.concatenate(contexts)
    frames = len(errors)
    column = {c: ctx[:, i] for i, c in enumerate(context)}
    predictor = Predictor(model, spec, dev)
    sample = FrameStream(data, split, labels, normalised=False, shuffle=False, moment=moment)
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
              "latency_frames": len(lat), "device": _device_name(dev), "threads": torch.get_num_threads(),
              "parameters": sum(p.numel() for p in model.parameters())
              + sum(b.numel() for b in model.buffers())}
    return ModelResult(str(path), spec, describe(spec), errors, column, timing)


def _device_name(device: torch.device) -> str:
    if device.type == "cuda":
        return torch.cuda.get_device_name(device)
    return f"cpu ({platform.processor() or platform.machine()}, {torch.get_num_threads()} threads)"


def evaluate(data, checkpoints, split: str = "test", device: str = "cpu", batch_size: int = 32,
             workers: int = 0, latency_frames: int = 100, log=print, layout: ReportLayout | None = None) -> Evaluation:
    """Evaluate each checkpoint on `split` of `data`; the report, laid out by `layout` (the world's; default: one
    column per output), is in `.markdown` and `.files`."""
    layout = layout or ReportLayout()
    ds = Dataset(Path(data))
    shards = ds.select(split)
    if not shards:
        raise DatasetError(f"dataset {data} has no frames in split '{split}'")
    results = [evaluate_model(p, data, split, device, batch_size, workers, latency_frames, log, layout)
               for p in checkpoints]
    ev = Evaluation(results, str(data), split, sum(r.timing["frames"] for r in results[:1]), len(shards),
                    world=ds.world, layout=layout)
    names = [r.name for r in results]
    for r in results:  # two checkpoints of one kind are told apart by file name
        if names.count(r.name) > 1:
            r.name = f"{r.name} ({Path(r.path).name})"
    ev.markdown = markdown(ev)
    ev.files = {"mae.md": ev.markdown, "mae.csv": mae_csv(ev), "mae_by_regime.csv": breakdown_csv(ev, "regime"),
                "mae_by_lanes.csv": breakdown_csv(ev, "lanes"), "speed.csv": speed_csv(ev),
                "mae.png": bar_chart(ev), "evaluation.json": summary(ev)}
    assert tuple(ev.files) == REPORT_FILES
    return ev


# --- tables -------------------------------------------------------------------------------------------------
def columns(ev: Evaluation) -> list[str]:
    return ev.layout.columns(ev.results)


def _fmt(v) -> str:
    if v is None:
        return "—"
    return f"{v:.3f}" if abs(v) < 100 else f"{v:.1f}"


def _table(short: dict[str, str], rows: list[tuple[str, dict]], cols: list[str], first: str = "model") -> str:
    lines = [f"| {first} | " + " | ".join(short.get(c, c) for c in cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for name, mae in rows:
        lines.append(f"| {name} | " + " | ".join(_fmt(mae.get(c)) for c in cols) + " |")
    return "\n".join(lines)


def masks(ev: Evaluation, r: ModelResult, by: str) -> list[tuple[str, np.ndarray]]:
    return ev.layout.masks(r, by)


def markdown(ev: Evaluation) -> str:
    cols, layout = columns(ev), ev.layout
    out = [layout.title, "", layout.intro(ev), "",
           _table(layout.short, [(r.name, r.mae()) for r in ev.results]
                  + [(f"*paper: {k}*", row) for k, row in layout.reference.items()], cols),
           ""]
    for by, title in (("regime", "By regime (dataset columns in_lane / on_marking)"), ("lanes", "By lane count")):
        out += [f"## {title}", ""]
        groups: dict[str, list[tuple[ModelResult, np.ndarray]]] = {}
        for r in ev.results:
            for name, m in masks(ev, r, by):
                groups.setdefault(name, []).append((r, m))
        for name, items in groups.items():
            if not items[0][1].any():
                continue
            out += [f"### {name}: {int(items[0][1].sum())} frames", "",
                    _table(layout.short, [(r.name, r.mae(m)) for r, m in items], cols), ""]
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
    rows += [["paper", k, "", ev.layout.reference_frames] + [row.get(c) for c in cols]
             for k, row in ev.layout.reference.items()]
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
            ev.layout.reference_key: dict(ev.layout.reference)}


def bar_chart(ev: Evaluation) -> np.ndarray:
    """Grouped bars of MAE per indicator, ours solid and the paper's hatched; one panel per unit/scale."""
    import matplotlib  # lazy: matplotlib takes 0.7 s to import and only the report's chart needs it
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # lazy: as matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # lazy: as matplotlib

    cols = columns(ev)
    panels = ev.layout.panels(cols)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    series = [(r.name, r.mae(), {"color": colors[k % len(colors)]}) for k, r in enumerate(ev.results)]
    series += [(f"paper: {k}", row, {"hatch": "//", "color": grey, "edgecolor": "0.2"})
               for (k, row), grey in zip(ev.layout.reference.items(), ("0.45", "0.65", "0.85"))]
    widths = [max(1.6, 0.9 * len(c)) for _, c in panels]
    fig, axes = plt.subplots(1, len(panels), figsize=(sum(widths) + 2, 4.2), dpi=100,
                             gridspec_kw={"width_ratios": widths})
    n = len(series)
    for ax, (title, names) in zip(np.atleast_1d(axes), panels):
        x = np.arange(len(names))
        for k, (label, mae, style) in enumerate(series):
            vals = [mae.get(c, np.nan) for c in names]
            ax.bar(x + (k - (n - 1) / 2) * 0.8 / n, vals, 0.8 / n, label=label, **style)
        ax.set_xticks(x, [ev.layout.short.get(c, c) for c in names], rotation=45 if len(names) > 3 else 0, fontsize=8)
        ax.set_title(title, fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    np.atleast_1d(axes)[0].set_ylabel("MAE")
    handles, labels = np.atleast_1d(axes)[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(n, 4), fontsize=8, frameon=False)
    fig.suptitle(f"MAE per indicator, split {ev.split} ({ev.frames} frames)", fontsize=10)
    fig.tight_layout(rect=(0, 0.12 + 0.04 * ((n - 1) // 4), 1, 0.95))
    canvas = fig.canvas
    assert isinstance(canvas, FigureCanvasAgg)   # the Agg backend, chosen above
    canvas.draw()
    rgb = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return rgb
