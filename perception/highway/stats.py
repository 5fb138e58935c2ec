"""What a highway dataset covers (drivestudio stats): the in-lane / on-marking / overlap shares, frames per lane
position, near cars, the spread of the angle, lane changes, speed and the expert's perturbations; histograms of
the 14 indicators with their inactive readings counted apart."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from core.declaration import WorldDeclaration
from core.worlds.highway import GAP_MAX, GAPS, INACTIVE, INDICATORS
from perception.dataset_stats import draw_histograms, header_rows, share, splits

if TYPE_CHECKING:  # the dataset reader (pyarrow, OpenCV) loads only when a dataset is read
    from perception.shards import Dataset

NEAR = 20.0  # [m] a car closer than this ahead counts as near
COLUMNS = INDICATORS + ("lanes_left", "lanes", "speed", "in_lane", "on_marking", "episode", "step", "track",
                        "perturbation")


class HighwayCoverage:
    def summarize(self, ds: Dataset, split: str | None = None) -> tuple[dict, dict]:
        """(summary, label arrays) of a split ("train", "val", "test" or None for all)."""
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
            "splits": splits(ds),
            "tracks": sorted(set(v["track"].tolist())),
            "share_in_lane_only": share(in_lane & ~on_marking),
            "share_on_marking_only": share(on_marking & ~in_lane),
            "share_overlap": share(in_lane & on_marking),
            "frames_per_lane_position": positions,
            "near_cars_under_20m": near,
            "angle_rad": {"min": round(float(angle.min()), 3) if n else 0.0,
                          "p1": round(float(np.percentile(angle, 1)), 3) if n else 0.0,
                          "p50": round(float(np.percentile(angle, 50)), 3) if n else 0.0,
                          "p99": round(float(np.percentile(angle, 99)), 3) if n else 0.0,
                          "max": round(float(angle.max()), 3) if n else 0.0,
                          "share_abs_over_0.2": share(np.abs(angle) > 0.2),
                          "share_abs_over_0.35": share(np.abs(angle) > 0.35)},
            "lane_changes": {"to_the_left": int(np.sum(moves < 0)), "to_the_right": int(np.sum(moves > 0))},
            "mean_speed_mps": round(float(np.mean(v["speed"])), 2) if n else 0.0,
            "perturbations": {p: share(v["perturbation"] == p) for p in sorted(set(v["perturbation"].tolist()))},
        }
        return summary, v

    def table(self, summary: dict) -> str:
        """The summary as a Markdown table."""
        rows = header_rows(summary)
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
        kinds = ", ".join(f"{k} {v:.0%}" for k, v in summary["perturbations"].items())
        rows.append(f"| perturbations | {kinds} |")
        return "\n".join(rows)

    def histograms(self, values: dict, out_dir: Path, decl: WorldDeclaration) -> list[Path]:
        def at_cap(name: str, active: np.ndarray) -> str:
            return f", {np.mean(active >= GAP_MAX):.0%} at {GAP_MAX:g}" if name in GAPS else ""
        return draw_histograms(values, out_dir, list(INDICATORS) + ["lanes_left", "speed"], dict(INACTIVE),
                               note=at_cap, bins={"lanes_left": np.arange(-0.5, 4.5)})
