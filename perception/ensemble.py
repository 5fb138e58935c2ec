"""An ensemble of trained regressors of one world, read as one model: every member reads the same frames, and
their estimates are combined output by output.

Why: a learned driver's lane-change collisions that a better reading would have avoided are single networks
reading a near car in the next lane as a free lane (docs/benchmark.md, crash clips: "misread"). Networks trained
from other seeds or on other data miss different cars, so the combination believes the closest gap any member
reads (the same asymmetry as the controller-side gap hold: a car seen by one is a car), and averages every other
output (angle, markings, `fast`, closing speeds), where errors of either sign cancel.

Members may estimate different outputs of one world; each output is combined over the members that estimate it.
So a network that learned only the cars beside and behind (a trunk of its own for the hard rear outputs, which
cost the forward gaps their accuracy when they share one: docs/explanation/learned-driving.md, "An ensemble of
networks") joins networks of the paper's 13,
and the ensemble estimates the union.

The members keep their own input statistics: the ensemble's input is the frame scaled to [0, 1] (mean 0, std 1
in its spec), and each member standardises it with the mean and std it was trained with. Its spec's options hold
each member's family, options and statistics (for a member of fewer outputs, `estimates`: the indices of the
ensemble's outputs it estimates, in its own order), and which outputs are gaps; the weights hold every member's.
Made from checkpoints by `drivestudio ensemble` (docs/explanation/learned-driving.md, "An ensemble of networks"),
never trained as a whole.
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
        estimates = [list(m.get("estimates", range(outputs))) for m in members]
        self.members = nn.ModuleList(family(m["name"]).build(inp, len(e), dict(m.get("options", {})))
                                     for m, e in zip(members, estimates))
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
        # members of fewer outputs: each one's outputs placed among the ensemble's by a one-hot map (its outputs,
        # the ensemble's), and which outputs each estimates; derived from the spec, so not in the weights
        self.partial = any(len(e) != outputs for e in estimates)
        if self.partial:
            eye = torch.eye(outputs)
            for i, e in enumerate(estimates):
                self.register_buffer(f"place_{i}", eye[e], persistent=False)
            self.register_buffer("estimated", torch.stack([eye[e].sum(dim=0) for e in estimates]) > 0,
                                 persistent=False)

    def forward(self, x: torch.Tensor, modes: torch.Tensor | None = None) -> torch.Tensor:
        """x: frames scaled to [0, 1] (the ensemble's mean 0, std 1) -> the combined normalised outputs."""
        means, stds = self.get_buffer("means"), self.get_buffer("stds")
        outs = [m((x - means[i]) / stds[i], modes) for i, m in enumerate(self.members)]
        if self.partial:
            return self._combine_partial(outs)
        stacked = torch.stack(outs)
        mean = stacked.mean(dim=0)
        if self.combine != "min":
            return mean
        # a gap's normalisation has a positive scale (core/worlds/highway.py), so the smallest output is the
        # closest car
        return torch.where(self.get_buffer("gaps"), stacked.min(dim=0).values, mean)

    def _combine_partial(self, outs: list[torch.Tensor]) -> torch.Tensor:
        """Each output over the members that estimate it (every output is estimated by one at least)."""
        placed = torch.stack([o @ self.get_buffer(f"place_{i}") for i, o in enumerate(outs)])   # 0 where not
        estimated = self.get_buffer("estimated").unsqueeze(1)                                   # (members, 1, out)
        mean = placed.sum(dim=0) / estimated.sum(dim=0)
        if self.combine != "min":
            return mean
        closest = torch.where(estimated, placed, torch.full_like(placed, float("inf"))).min(dim=0).values
        return torch.where(self.get_buffer("gaps"), closest, mean)


def _fits(decl) -> str:
    return "an ensemble is made from trained checkpoints by `python -m drivestudio.ensemble`, not trained"


def _describe(spec: dict) -> str:
    opts = spec["options"]
    titles = sorted({m.get("title", m["name"]) for m in opts["members"]})
    return f"Ensemble of {len(opts['members'])} {', '.join(titles)} (gaps: {opts.get('combine', 'min')})"


def _build(inp: ModelInput, outputs: int, options: dict) -> Ensemble:
    return Ensemble(inp, outputs, options)


register(Family("ensemble", "Ensemble", _build, _fits, temporal=True, describe=_describe))
