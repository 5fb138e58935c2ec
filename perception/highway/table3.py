"""The highway's evaluation report: Liu and Wang's Table 3 (Deeper Direct Perception in Autonomous Driving), the
13 indicators in the paper's order beside the paper's three rows, split by regime (the dataset's in_lane /
on_marking columns: in lane only, on marking only, the overlap where both systems are active) and by lane count."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.worlds.highway import PAPER_INDICATORS
from perception.mae_report import Evaluation, ModelResult, ReportLayout

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


@dataclass
class Table3Layout(ReportLayout):
    title: str = "# Perception: mean absolute error per indicator"
    context: tuple[str, ...] = ("in_lane", "on_marking", "lanes")
    reference: dict[str, dict[str, float]] = field(
        default_factory=lambda: {k: dict(zip(PAPER_INDICATORS, v)) for k, v in TABLE3.items()})
    reference_frames: int = 10000
    reference_key: str = "paper_table3"
    short: dict[str, str] = field(default_factory=lambda: dict(SHORT))

    def columns(self, results: list[ModelResult]) -> list[str]:
        extra = [n for n in ("fast", "lanes_left") if any(n in r.labels for r in results)]
        return list(PAPER_INDICATORS) + extra

    def intro(self, ev: Evaluation) -> str:
        return (f"Split `{ev.split}` of `{ev.data}`: {ev.frames} frames in {ev.episodes} episodes. MAE in the "
                "indicators' units (angle in rad, toMarking_* and dist_* in m), laid out as Liu and Wang's Table 3 "
                "(Deeper Direct Perception in Autonomous Driving). Their rows were measured on 10,000 TORCS "
                "frames, not on these: they are a reference, not a like-for-like comparison.")

    def masks(self, r: ModelResult, by: str) -> list[tuple[str, np.ndarray]]:
        n = len(r.errors)
        if by == "regime":
            in_lane = r.context.get("in_lane", np.zeros(n)) > 0.5
            on_marking = r.context.get("on_marking", np.zeros(n)) > 0.5
            out = [(name, (in_lane == a) & (on_marking == b)) for name, (a, b) in REGIMES.items()]
            return [(name, m) for name, m in out if m.any() or name != "neither"]
        lanes = r.context.get("lanes", np.zeros(n)).round().astype(int)
        return [(f"{k} lane{'s' if k != 1 else ''}", lanes == k) for k in sorted(set(lanes.tolist()))]

    def panels(self, cols: list[str]) -> list[tuple[str, list[str]]]:
        panels = [("angle [rad]", ["angle"]), ("toMarking [m]", [c for c in cols if c.startswith("toMarking")]),
                  ("dist [m]", [c for c in cols if c.startswith("dist")])]
        extra = [c for c in cols if c in ("fast", "lanes_left")]
        return panels + ([("extra", extra)] if extra else [])
