"""Loss curves beside a checkpoint: `<out>.loss.csv` and `<out>.loss.png`, written atomically (every trainer)."""
from __future__ import annotations

import csv
import io
from pathlib import Path

from core.files import atomic_write


def curve_paths(out) -> tuple[Path, Path]:
    out = Path(out)
    return out.with_name(out.name + ".loss.csv"), out.with_name(out.name + ".loss.png")


def write_curves(out, history: list[dict], x: str = "iteration", title: str = "") -> None:
    """The loss history as CSV and as a PNG plot (log scale), both beside the checkpoint, atomically."""
    import matplotlib  # lazy: matplotlib takes 0.7 s to import and only a finished run's plot needs it
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # lazy: as matplotlib

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
