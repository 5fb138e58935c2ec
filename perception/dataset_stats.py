"""What a dataset covers, for any declared world: frames per split (and how the split was made), the spread of every
label, the balance of behavioural modes and the share of every flag of the truth record (collisions, corrections,
...), and per-label histograms. A world with more to say supplies its own Coverage through its plugin (the
highway's: perception/highway/stats.py).

Reads label columns only (no image is decoded), so it runs at millions of frames per minute.
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from core.declaration import WorldDeclaration

if TYPE_CHECKING:  # the dataset reader (pyarrow, OpenCV) loads only when a dataset is read
    from perception.shards import Dataset


class Coverage(Protocol):
    """What `drivestudio stats` reports of a dataset of one world."""

    def summarize(self, ds: Dataset, split: str | None = None) -> tuple[dict, dict]: ...

    def table(self, summary: dict) -> str: ...

    def histograms(self, values: dict, out_dir: Path, decl: WorldDeclaration) -> list[Path]: ...


def share(mask: np.ndarray) -> float:
    return round(float(np.mean(mask)), 4) if mask.size else 0.0


def splits(ds: Dataset) -> dict:
    """How the split was made and what each split holds."""
    rule = ds.manifest.get("split_rule", "episode % 10: 0-7 train, 8 validation, 9 test")
    lengths = sorted({s.frames for s in ds.shards})
    how = f"{rule}, whole episodes of {lengths[-1] if len(lengths) == 1 else f'{lengths[0]}-{lengths[-1]}'} frames"
    return {"rule": how, **{s: {"episodes": len(ds.select(s)), "frames": ds.frames(s)}
                            for s in ("train", "val", "test")}}


def header_rows(summary: dict) -> list[str]:
    """The table's first rows: world, frames, episodes and the split."""
    rows = ["| measure | value |", "|---|---|"]
    for key in ("world", "frames", "episodes"):
        rows.append(f"| {key} | {summary[key]} |")
    sp = summary["splits"]
    rows.append(f"| split | {sp['rule']}: " + ", ".join(f"{k} {sp[k]['frames']} frames in {sp[k]['episodes']} "
                                                        f"episodes" for k in ("train", "val", "test")) + " |")
    return rows


class AnyWorld:
    """The coverage every declared world has."""

    def summarize(self, ds: Dataset, split: str | None = None) -> tuple[dict, dict]:
        """(summary, label arrays) of a split ("train", "val", "test" or None for all)."""
        decl = ds.declaration
        flags = [q.name for q in decl.truth if q.kind == "bool"]
        columns = list(dict.fromkeys(list(decl.label_names) + flags + ([decl.mode_field] if decl.mode_field else [])
                                     + ["episode", "step"]))
        v = ds.labels(split, columns)
        n = len(v["episode"])
        spread = {}
        for name in decl.label_names:
            x = v[name].astype(np.float64)
            spread[name] = {k: round(float(f(x)), 4) if n else 0.0 for k, f in
                            (("min", np.min), ("p5", lambda a: np.percentile(a, 5)), ("median", np.median),
                             ("p95", lambda a: np.percentile(a, 95)), ("max", np.max), ("std", np.std))}
        order = np.lexsort((v["step"], v["episode"]))
        same = v["episode"][order][1:] == v["episode"][order][:-1]

        def events(flag: np.ndarray) -> int:
            """How often a flag turns on within an episode (an obstacle met, a correction begun, a collision)."""
            f = flag[order].astype(bool)
            return int(f[:1].sum() + np.sum(f[1:] & ~f[:-1] & same) + np.sum(f[1:] & ~same))

        summary: dict[str, Any] = {"world": ds.world, "frames": n, "episodes": int(len(np.unique(v["episode"]))),
                   "splits": splits(ds), "labels": spread,
                   "flags": {name: share(v[name].astype(bool)) for name in flags},
                   "flag_events": {name: events(v[name]) for name in flags}}
        if decl.mode_field:
            modes = v[decl.mode_field].astype(int)
            summary["modes"] = {m: share(modes == i) for i, m in enumerate(decl.modes)}
            for m_i, m in enumerate(decl.modes):
                summary.setdefault("labels_by_mode", {})[m] = {
                    name: round(float(np.mean(v[name][modes == m_i])), 4) if np.any(modes == m_i) else None
                    for name in decl.label_names}
        return summary, v

    def table(self, summary: dict) -> str:
        """The summary as a Markdown table."""
        rows = header_rows(summary)
        for name, st in summary["labels"].items():
            rows.append(f"| {name} | min {st['min']}, 5% {st['p5']}, median {st['median']}, 95% {st['p95']}, "
                        f"max {st['max']}, std {st['std']} |")
        if "modes" in summary:
            modes = ", ".join(f"{k} {v:.1%}" for k, v in summary["modes"].items())
            rows.append(f"| behavioural modes | {modes} |")
            for mode, means in summary["labels_by_mode"].items():
                rows.append(f"| mean labels, {mode} | " + ", ".join(f"{k} {v}" for k, v in means.items()) + " |")
        for name, part in summary["flags"].items():
            rows.append(f"| {name.replace('_', ' ')} | {part:.1%} of frames, {summary['flag_events'][name]} times "
                        f"(turning on within an episode) |")
        return "\n".join(rows)

    def histograms(self, values: dict, out_dir: Path, decl: WorldDeclaration) -> list[Path]:
        inactive = {lab.name: lab.inactive for lab in decl.labels if lab.inactive is not None}
        return draw_histograms(values, out_dir, list(decl.label_names), inactive)


def draw_histograms(values: dict, out_dir: Path, names: list[str], inactive: dict[str, float],
                    note: Callable[[str, np.ndarray], str] | None = None, bins: dict | None = None) -> list[Path]:
    """One PNG per label (its active values; the share of inactive readings in the title) and an overview grid.
    note(name, active values) adds to a title; bins[name] overrides the 50 equal bins."""
    import matplotlib  # lazy: matplotlib takes most of a second to import and only stats draws
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # lazy: as matplotlib

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    cols = 4 if len(names) > 4 else len(names)
    grid, axes = plt.subplots(-(-len(names) // cols), cols, figsize=(4 * cols, 3 * -(-len(names) // cols)),
                              squeeze=False)
    for ax_grid, name in zip(axes.flat, names):
        x = values[name].astype(np.float64)
        off = x == inactive[name] if name in inactive else np.zeros(len(x), bool)
        active = x[~off]
        title = name + (f" (inactive {np.mean(off):.0%})" if name in inactive else "")
        if note is not None and active.size:
            title += note(name, active)
        fig, ax = plt.subplots(figsize=(5, 3.2))
        for a in (ax, ax_grid):
            a.hist(active, bins=(bins or {}).get(name, 50), color="#3b6ea5")
            a.set_title(title, fontsize=9)
            a.set_ylabel("frames", fontsize=8)
        fig.tight_layout()
        path = out_dir / f"hist-{name}.png"
        fig.savefig(path, dpi=80)
        plt.close(fig)
        written.append(path)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    grid.tight_layout()
    overview = out_dir / "histograms.png"
    grid.savefig(overview, dpi=70)
    plt.close(grid)
    return [overview] + written
