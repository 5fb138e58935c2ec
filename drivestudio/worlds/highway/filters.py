"""The highway's estimate filters (docs/controller.md): what a driver spec's `@filter=value` names, and the filters
themselves, applied in place to a model's estimate record before the controller, in the order of FILTERS.

    smoothing=A     every estimate: e = A e_previous + (1 - A) e_now
    gap_hold=A      the gaps (dist_*): a shorter one at once, a longer one approached with A
    pass_memory=S   a car being passed in a neighbour lane, carried on unseen for at most S seconds
    rear_memory=S   a car the mirror loses while it closes in alongside, held for at most S seconds
"""
from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np

from controller.highway.chen import KEEP, LEFT_2, RIGHT_2
from controller.highway.pass_memory import PassMemory
from controller.highway.rear_memory import RearMemory
from core.worlds.highway import HIGHWAY
from drivestudio.driver_spec import DriverSpec, EstimateFilter
from drivestudio.errors import UsageError

MAX_FACTOR = 0.95        # smoothing and gap hold: above it an estimate would hardly follow the frames
MAX_MEMORY = 60.0        # [s] the longest a memory carries a car unseen

FILTERS = {f.name: f for f in (
    EstimateFilter("smoothing", MAX_FACTOR, "", "exponential smoothing of every estimate"),
    EstimateFilter("gap_hold", MAX_FACTOR, "", "the gaps: a shorter one at once, a longer one smoothed"),
    EstimateFilter("pass_memory", MAX_MEMORY, "s", "a car being passed, carried on once the camera loses it"),
    EstimateFilter("rear_memory", MAX_MEMORY, "s", "a car the mirror loses alongside, held (rear-label models)"),
)}

ESTIMATE = tuple(HIGHWAY.estimate_names)
_INDEX = {n: i for i, n in enumerate(ESTIMATE)}
_GAPS = [i for i, n in enumerate(ESTIMATE) if n.startswith("dist_")]
_NEIGHBOUR_GAPS = [_INDEX["dist_LL"], _INDEX["dist_RR"]]   # what the controller's rule 1 reads
_REAR_SIDES = [(_INDEX[f"dist_{k}B"], _INDEX[f"closing_{k}B"]) for k in "LR"]   # what rule L1 reads


class Filter(Protocol):
    """One filter: the estimate record in place, given the host's speed [m/s] and the controller's state."""

    def __call__(self, est: np.ndarray, speed: float, state: str) -> None: ...


class Smoothing:
    """Every estimate mixed with the last record the controller read: that record, held by reference, is the one
    the later filters finish in place, so the smoothing follows what was driven on."""

    def __init__(self, factor: float):
        self.factor = factor
        self._last: np.ndarray | None = None

    def __call__(self, est: np.ndarray, speed: float, state: str) -> None:
        if self._last is not None:
            est[:] = np.where(np.isfinite(self._last), self.factor * self._last + (1 - self.factor) * est, est)
        self._last = est


class GapHold:
    """A car coming closer is taken at once, one going away slowly: a gap misread long for a frame does not open a
    lane the controller would move into."""

    def __init__(self, factor: float):
        self.factor = factor
        self._held: np.ndarray | None = None

    def __call__(self, est: np.ndarray, speed: float, state: str) -> None:
        if self._held is not None:
            est[_GAPS] = np.fmin(est[_GAPS], self.factor * self._held + (1 - self.factor) * est[_GAPS])
        self._held = est[_GAPS].copy()


class Memories:
    """The memories of cars out of view: the pass memory on the neighbour gaps ahead, the rear memory on the gaps
    and closing speeds behind (one filter: with the rear memory, the mirror takes a passed car over from the pass
    memory). A lane change forgets them (the lanes change meaning): the pass memory for its whole length, the rear
    memory once the host is on the marking (until then rule L2 reads it)."""

    def __init__(self, pass_s: float, rear_s: float):
        self.passing = [PassMemory(max_s=pass_s) for _ in _NEIGHBOUR_GAPS] if pass_s > 0 else []
        self.rear = [RearMemory(max_s=rear_s) for _ in _REAR_SIDES] if rear_s > 0 else []

    def __call__(self, est: np.ndarray, speed: float, state: str) -> None:
        for k, (memory, i) in enumerate(zip(self.passing, _NEIGHBOUR_GAPS)):
            if state != KEEP:
                memory.reset()
            behind = bool(est[_REAR_SIDES[k][0]] < self.rear[k].near) if self.rear else None
            est[i] = memory.filter(float(est[i]), speed, behind)
        for rear, (g, c) in zip(self.rear, _REAR_SIDES):
            if state in (LEFT_2, RIGHT_2):
                rear.reset()
            est[g], est[c] = rear.filter(float(est[g]), float(est[c]))


def make_filters(spec: DriverSpec, lookout: bool) -> list[Filter]:
    """The filters of a checkpoint's driver spec, in FILTERS' order. The rear memory holds the rear labels, which
    only a model that reads behind (a lookout driver) estimates."""
    if spec.get("rear_memory") and not lookout:
        raise UsageError(f"{spec}: rear_memory holds the rear labels (dist_LB, dist_RB, closing_LB, closing_RB), "
                         f"which {Path(spec.source).name} does not estimate")
    out: list[Filter] = []
    if spec.get("smoothing"):
        out.append(Smoothing(spec.get("smoothing")))
    if spec.get("gap_hold"):
        out.append(GapHold(spec.get("gap_hold")))
    if spec.get("pass_memory") or spec.get("rear_memory"):
        out.append(Memories(spec.get("pass_memory"), spec.get("rear_memory")))
    return out
