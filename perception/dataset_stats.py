"""What a dataset covers, and label histograms. For the highway: regimes, lane positions, near cars, angles, lane
changes; for any world: frames per split, the spread of every label, the balance of behavioural modes and the share
of every flag of the truth record (collisions, corrections, ...).

Reads label columns only (no image is decoded), so it runs at millions of frames per minute.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from core.worlds.highway import GAP_MAX, GAPS, INACTIVE, INDICATORS
from perception.shards import Dataset

NEAR = 20.0  # [m] a car closer than this ahead counts as near
COLUMNS = INDICATORS + ("lanes_left", "lanes", "speed", "in_lane", "on_marking", "episode", "step", "track",
                        "perturbation")


def _share(mask: np.ndarray) -> float:
    return round(float(np.mean(mask)), 4) if mask.size else 0.0


def _splits(ds: Dataset) -> dict:
    """How the split was made and what each split holds."""
    rule = ds.manifest.get("split_rule", "episode % 10: 0-7 train, 8 validation, 9 test")
    lengths = sorted({s.frames for s in ds.shards})
    how = f"{rule}, whole episodes of {lengths[-1] if len(lengths) == 1 else f'{lengths[0]}-{lengths[-1]}'} frames"
    return {"rule": how, **{s: {"episodes": len(ds.select(s)), "frames": ds.frames(s)}
                            for s in ("train", "val", "test")}}


def summarize(ds: Dataset, split: str | None = None) -> tuple[dict, dict]:
    """(summary, label arrays) of a split ("train", "val", "test" or None for all)."""
    if ds.world != "highway":
        return summarize_any(ds, split)
    v = ds.labels(split, COLUMNS)
    n = len(v["angle"])
    in_lane, on_marking = v["in_lane"].astype(bool), v["on_marking"].astype(bool)
    angle = v["angle"].astype(np.float64)
    lanes, lanes_left = v["lanes"].astype(int), v["lanes_left"].astype(int)
    # lane changes: the host car's lane index changes between consecutive frames of one episode
    order = np.lexsort((v["step"], v["episode"]))
    ep, ll = v["episode"][order], lanes_left[order]
    same = ep[1:] == ep[:-1]
    moves = np.diff(ll)[same]
    near = {}
    for name in GAPS:
        g = v[name].astype(np.float64)
        near[name] = int(np.sum(g < NEAR))
    positions = {}
    for count in sorted(set(lanes.tolist())):
        m = lanes == count
        positions[f"{count} lane(s)"] = {f"lane {k}": int(np.sum(m & (lanes_left == k))) for k in range(count)}
    summary = {
        "world": ds.world,
        "frames": n,
        "episodes": int(len(np.unique(v["episode"]))),
        "splits": _splits(ds),
        "tracks": sorted(set(v["track"].tolist())),
        "share_in_lane_only": _share(in_lane & ~on_marking),
        "share_on_marking_only": _share(on_marking & ~in_lane),
        "share_overlap": _share(in_lane & on_marking),
        "frames_per_lane_position": positions,
        "near_cars_under_20m": near,
        "angle_rad": {"min": round(float(angle.min()), 3) if n else 0.0,
                      "p1": round(float(np.percentile(angle, 1)), 3) if n else 0.0,
                      "p50": round(float(np.percentile(angle, 50)), 3) if n else 0.0,
                      "p99": round(float(np.percentile(angle, 99)), 3) if n else 0.0,
                      "max": round(float(angle.max()), 3) if n else 0.0,
                      "share_abs_over_0.2": _share(np.abs(angle) > 0.2),
                      "share_abs_over_0.35": _share(np.abs(angle) > 0.35)},
        "lane_changes": {"to_the_left": int(np.sum(moves < 0)), "to_the_right": int(np.sum(moves > 0))},
        "mean_speed_mps": round(float(np.mean(v["speed"])), 2) if n else 0.0,
        "perturbations": {p: _share(v["perturbation"] == p) for p in sorted(set(v["perturbation"].tolist()))},
    }
    return summary, v


def summarize_any(ds: Dataset, split: str | None = None) -> tuple[dict, dict]:
    """The summary of a dataset of any world: splits, label spread, mode balance, flag shares."""
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

    summary = {"world": ds.world, "frames": n, "episodes": int(len(np.unique(v["episode"]))),
               "splits": _splits(ds), "labels": spread,
               "flags": {name: _share(v[name].astype(bool)) for name in flags},
               "flag_events": {name: events(v[name]) for name in flags}}
    if decl.mode_field:
        modes = v[decl.mode_field].astype(int)
        summary["modes"] = {m: _share(modes == i) for i, m in enumerate(decl.modes)}
        for m_i, m in enumerate(decl.modes):
            summary.setdefault("labels_by_mode", {})[m] = {
                name: round(float(np.mean(v[name][modes == m_i])), 4) if np.any(modes == m_i) else None
                for name in decl.label_names}
    return summary, v


def table(summary: dict) -> str:
    """The summary as a Markdown table."""
    rows = ["| measure | value |", "|---|---|"]
    for key in ("world", "frames", "episodes"):
        rows.append(f"| {key} | {summary[key]} |")
    sp = summary["splits"]
    rows.append(f"| split | {sp['rule']}: " + ", ".join(f"{k} {sp[k]['frames']} frames in {sp[k]['episodes']} "
                                                        f"episodes" for k in ("train", "val", "test")) + " |")
    if summary["world"] != "highway":
        return _table_any(summary, rows)
    rows.append(f"| tracks | {len(summary['tracks'])}: {', '.join(summary['tracks'])} |")
    for key in ("share_in_lane_only", "share_on_marking_only", "share_overlap"):
        rows.append(f"| {key.replace('_', ' ')} | {summary[key]:.1%} |")
    for lanes, counts in summary["frames_per_lane_position"].items():
        rows.append(f"| frames per lane, {lanes} | {', '.join(f'{k}: {c}' for k, c in counts.items())} |")
    rows.append("| frames with a car under 20 m ahead | "
                + ", ".join(f"{k}: {c}" for k, c in summary["near_cars_under_20m"].items()) + " |")
    a = summary["angle_rad"]
    rows.append(f"| angle [rad] | min {a['min']}, 1% {a['p1']}, median {a['p50']}, 99% {a['p99']}, max {a['max']}; "
                f"|angle| > 0.2: {a['share_abs_over_0.2']:.1%}, > 0.35: {a['share_abs_over_0.35']:.1%} |")
    lc = summary["lane_changes"]
    rows.append(f"| lane changes | {lc['to_the_left']} to the left, {lc['to_the_right']} to the right |")
    rows.append(f"| mean speed | {summary['mean_speed_mps']} m/s |")
    rows.append("| perturbations | " + ", ".join(f"{k} {v:.0%}" for k, v in summary["perturbations"].items()) + " |")
    return "\n".join(rows)


def _table_any(summary: dict, rows: list[str]) -> str:
    for name, st in summary["labels"].items():
        rows.append(f"| {name} | min {st['min']}, 5% {st['p5']}, median {st['median']}, 95% {st['p95']}, "
                    f"max {st['max']}, std {st['std']} |")
    if "modes" in summary:
        rows.append("| behavioural modes | " + ", ".join(f"{k} {v:.1%}" for k, v in summary["modes"].items()) + " |")
        for mode, means in summary["labels_by_mode"].items():
            rows.append(f"| mean labels, {mode} | " + ", ".join(f"{k} {v}" for k, v in means.items()) + " |")
    for name, share in summary["flags"].items():
        rows.append(f"| {name.replace('_', ' ')} | {share:.1%} of frames, {summary['flag_events'][name]} times "
                    f"(turning on within an episode) |")
    return "\n".join(rows)


def histograms(values: dict, out_dir: Path, decl=None) -> list[Path]:
    """One PNG per indicator (active values; the share of inactive readings in the title) and an overview."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    names = list(INDICATORS) + ["lanes_left", "speed"] if decl is None or decl.name == "highway" else \
        list(decl.label_names)
    written = []
    cols = 4 if len(names) > 4 else len(names)
    grid, axes = plt.subplots(-(-len(names) // cols), cols, figsize=(4 * cols, 3 * -(-len(names) // cols)),
                              squeeze=False)
    for ax_grid, name in zip(axes.flat, names):
        x = values[name].astype(np.float64)
        inactive = x == INACTIVE[name] if name in INACTIVE else np.zeros(len(x), bool)
        active = x[~inactive]
        title = name + (f" (inactive {np.mean(inactive):.0%})" if name in INACTIVE else "")
        if name in GAPS:
            title += f", {np.mean(active >= GAP_MAX):.0%} at {GAP_MAX:g}" if active.size else ""
        bins = np.arange(-0.5, 4.5) if name == "lanes_left" else 50
        if not active.size:
            active = np.zeros(0)
        fig, ax = plt.subplots(figsize=(5, 3.2))
        for a in (ax, ax_grid):
            a.hist(active, bins=bins, color="#3b6ea5")
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
