"""What an evaluation measured (ModelResult, Evaluation) and how a world lays its report out (ReportLayout). Plain
data, numpy only, so that a world's plugin can name its layout without importing torch."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class ReportLayout:
    """How an evaluation report is laid out for the models of one world. This one suits any world: one column per
    output, no reference rows, no breakdowns, one bar-chart panel per label."""

    title: str = "# Perception: mean absolute error per output"
    context: tuple[str, ...] = ()        # dataset columns read beside the labels, for the breakdowns
    reference: dict[str, dict[str, float]] = field(default_factory=dict)   # rows from the literature
    reference_frames: int = 0            # the frames those rows were measured on
    reference_key: str = "reference"     # evaluation.json's key for them
    short: dict[str, str] = field(default_factory=dict)   # column headings

    def columns(self, results: list[ModelResult]) -> list[str]:
        return list(dict.fromkeys(n for r in results for n in r.labels))

    def intro(self, ev: Evaluation) -> str:
        return (f"Split `{ev.split}` of `{ev.data}` ({ev.world} world): {ev.frames} samples in {ev.episodes} "
                "episodes. MAE per output in the labels' units.")

    def masks(self, r: ModelResult, by: str) -> list[tuple[str, np.ndarray]]:
        """The breakdown of `by` ("regime", "lanes"): (name, mask over the samples) pairs."""
        return []

    def panels(self, cols: list[str]) -> list[tuple[str, list[str]]]:
        groups: dict[str, list[str]] = {}
        for c in cols:
            groups.setdefault(c.split("+", 1)[0], []).append(c)
        return list(groups.items())


@dataclass
class ModelResult:
    path: str
    spec: dict
    name: str
    errors: np.ndarray        # (samples, outputs) absolute errors in the labels' units
    context: dict[str, np.ndarray] = field(default_factory=dict)   # the layout's context columns, per sample
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
    layout: ReportLayout = field(default_factory=ReportLayout)
    markdown: str = ""
    files: dict = field(default_factory=dict)  # file name -> str (text), np.ndarray (RGB image) or dict (JSON)
