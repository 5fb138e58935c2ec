"""An ensemble of trained regressors of one world, read as one model: every member reads the same frames, and
their estimates are combined output by output.

Why: a learned driver's lane-change collisions that a better reading would have avoided are single networks
reading a near car in the next lane as a free lane (docs/benchmark.md, crash clips: "misread"). Networks trained
from other seeds or on other data miss different cars, so the combination believes the closest gap any member
reads (the same asymmetry as the controller-side gap hold: a car seen by one is a car), and averages every other
output (angle, markings, `fast`, closing speeds), where errors of either sign cancel.

The members keep their own input statistics: the ensemble's input is the frame scaled to [0, 1] (mean 0, std 1
in its spec), and each member standardises it with the mean and std it was trained with. Its spec's options hold
each member's family, options and statistics, and which outputs are gaps; the weights hold every member's.
Made from checkpoints by `python -m drivestudio.ensemble` (docs/aggregation.md), never trained as a whole.
"""
from __future__ import annotations

import torch
from torch import nn

from perception.models import Family, ModelInput, family, register

GAP_PREFIX = "dist_"       # outputs whose closest reading is believed (the highway's gaps, front and rear)
COMBINE = ("min", "mean")  # how the gaps are combined


class Ensemble(nn.Module):
    def __init__(self, inp: ModelInput, outputs: int, options: dict) -> None:
        super().__init__()
        members = options["members"]
        self.members = nn.ModuleList(family(m["name"]).build(inp, outputs, dict(m.get("options", {})))
                                     for m in members)
        c = inp.channels
        # (members, C, 1, 1): rank 4, as every tensor of a model the predictor puts in channels-last format
        self.register_buffer("means", torch.tensor([m["mean"] for m in members], dtype=torch.float32)
                             .view(len(members), c, 1, 1))
        self.register_buffer("stds", torch.tensor([m["std"] for m in members], dtype=torch.float32)
                             .view(len(members), c, 1, 1))
        gaps = torch.zeros(outputs, dtype=torch.bool)
        gaps[list(options.get("gaps", []))] = True
        self.register_buffer("gaps", gaps)
        self.combine = options.get("combine", "min")

    def forward(self, x: torch.Tensor, modes: torch.Tensor | None = None) -> torch.Tensor:
        """x: frames scaled to [0, 1] (the ensemble's mean 0, std 1) -> the combined normalised outputs."""
        means, stds = self.get_buffer("means"), self.get_buffer("stds")
        outs = torch.stack([m((x - means[i]) / stds[i], modes) for i, m in enumerate(self.members)])
        mean = outs.mean(dim=0)
        if self.combine != "min":
            return mean
        # a gap's normalisation has a positive scale (core/worlds/highway.py), so the smallest output is the
        # closest car
        return torch.where(self.get_buffer("gaps"), outs.min(dim=0).values, mean)


def _fits(decl) -> str:
    return "an ensemble is made from trained checkpoints by `python -m drivestudio.ensemble`, not trained"


def _describe(spec: dict) -> str:
    opts = spec["options"]
    titles = sorted({m.get("title", m["name"]) for m in opts["members"]})
    return f"Ensemble of {len(opts['members'])} {', '.join(titles)} (gaps: {opts.get('combine', 'min')})"


def _build(inp: ModelInput, outputs: int, options: dict) -> Ensemble:
    return Ensemble(inp, outputs, options)


register(Family("ensemble", "Ensemble", _build, _fits, temporal=True, describe=_describe))
