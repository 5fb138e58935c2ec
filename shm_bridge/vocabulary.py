"""The vocabulary every package shares: indicator names and order, inactive values, the training
normalisation and the driving action.

This module is the single owner of these facts (docs/affordances.md in prose). It sits at the bottom of
the dependency graph: sim, perception, controller and the bridge import it; it imports only numpy.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Canonical order: the seed paper's Table 1, then `fast`.
INDICATORS: tuple[str, ...] = (
    "angle",
    "toMarking_LL", "toMarking_ML", "toMarking_MR", "toMarking_RR",
    "dist_LL", "dist_MM", "dist_RR",
    "toMarking_L", "toMarking_M", "toMarking_R",
    "dist_L", "dist_R",
    "fast",
)
PAPER_INDICATORS: tuple[str, ...] = INDICATORS[:13]
INDEX: dict[str, int] = {name: i for i, name in enumerate(INDICATORS)}

IN_LANE: tuple[str, ...] = INDICATORS[1:8]       # the in-lane system (indicators 2-8)
ON_MARKING: tuple[str, ...] = INDICATORS[8:13]   # the on-marking system (indicators 9-13)
GAPS: tuple[str, ...] = ("dist_LL", "dist_MM", "dist_RR", "dist_L", "dist_R")

# Labels recorded beside the 14 (seed 002 §6.5 proposes lanes_left as the fix for off-by-one-lane errors).
EXTRA_LABELS: tuple[str, ...] = ("lanes_left", "lanes", "speed")

GAP_MAX = 60.0       # [m] gap of an active, existing lane with no car ahead within it
GAP_INACTIVE = 75.0  # [m] gap of an inactive system or of a lane that does not exist

INACTIVE: dict[str, float] = {
    "toMarking_LL": -9.5, "toMarking_ML": -5.5, "toMarking_MR": 5.5, "toMarking_RR": 9.5,
    "dist_LL": GAP_INACTIVE, "dist_MM": GAP_INACTIVE, "dist_RR": GAP_INACTIVE,
    "toMarking_L": -7.0, "toMarking_M": 3.5, "toMarking_R": 7.0,
    "dist_L": GAP_INACTIVE, "dist_R": GAP_INACTIVE,
}

# DeepDriving's affine maps to about [0.1, 0.9]: normalised = value * scale + offset.
# lanes_left is ours (0..3 -> 0.1..0.7); angle is additionally clipped to [0, 1].
NORMALISATION: dict[str, tuple[float, float]] = {
    "angle": (1 / 1.1, 0.5),
    "toMarking_LL": (0.14545, 1.48181), "toMarking_ML": (0.16, 0.98),
    "toMarking_MR": (0.16, 0.02), "toMarking_RR": (0.14545, -0.48181),
    "dist_LL": (1 / 95, 0.12), "dist_MM": (1 / 95, 0.12), "dist_RR": (1 / 95, 0.12),
    "toMarking_L": (0.17778, 1.34445), "toMarking_M": (0.14545, 0.39091), "toMarking_R": (0.17778, -0.34445),
    "dist_L": (1 / 95, 0.12), "dist_R": (1 / 95, 0.12),
    "fast": (0.6, 0.2),
    "lanes_left": (0.2, 0.1),
}

STEER_LOCK_RAD = 0.541052  # full lock of the host car; steer = 1 means this wheel angle, to the left


def markings(lanes: int, lane_width: float) -> np.ndarray:
    """Lateral offsets [m] of the markings m_j = (N/2 - j) w, j = 0..N: the left edge first (d positive left)."""
    return (lanes / 2 - np.arange(lanes + 1)) * lane_width


def lane_centres(lanes: int, lane_width: float) -> np.ndarray:
    """Lateral offsets [m] of the lane centres c_k = (N/2 - k - 1/2) w, k = 0..N-1: the leftmost lane first."""
    return (lanes / 2 - np.arange(lanes) - 0.5) * lane_width


def label_set(fast: bool = False, lanes_left: bool = False) -> tuple[str, ...]:
    """The regression targets of a model: the paper's 13, optionally `fast` and `lanes_left`."""
    names = PAPER_INDICATORS + (("fast",) if fast else ()) + (("lanes_left",) if lanes_left else ())
    return names


def _affine(names: tuple[str, ...] | list[str]) -> tuple[np.ndarray, np.ndarray]:
    unknown = [n for n in names if n not in NORMALISATION]
    if unknown:
        raise KeyError(f"no normalisation for {unknown}")
    scale = np.array([NORMALISATION[n][0] for n in names], dtype=np.float32)
    offset = np.array([NORMALISATION[n][1] for n in names], dtype=np.float32)
    return scale, offset


def normalise(values, names) -> np.ndarray:
    """Map label values (last axis ordered as `names`) to DeepDriving's training range, about [0.1, 0.9]."""
    scale, offset = _affine(tuple(names))
    out = np.asarray(values, dtype=np.float32) * scale + offset
    if "angle" in names:
        i = list(names).index("angle")
        out[..., i] = np.clip(out[..., i], 0.0, 1.0)
    return out


def denormalise(values, names) -> np.ndarray:
    """Inverse of `normalise` (angle's clip aside): network outputs back to metres, radians and flags."""
    scale, offset = _affine(tuple(names))
    return (np.asarray(values, dtype=np.float32) - offset) / scale


def indicators_to_dict(values) -> dict[str, float]:
    """The 14 indicators as a {DeepDriving name: value} mapping, in canonical order."""
    values = np.asarray(values, dtype=np.float64)
    if values.shape != (len(INDICATORS),):
        raise ValueError(f"expected {len(INDICATORS)} indicators, got shape {values.shape}")
    return {name: float(v) for name, v in zip(INDICATORS, values)}


@dataclass(frozen=True)
class Action:
    """A TORCS-style driving command.

    steer: [-1, 1], positive turns left, 1 = full lock (STEER_LOCK_RAD).
    accel, brake: [0, 1] pedal fractions.
    """

    steer: float = 0.0
    accel: float = 0.0
    brake: float = 0.0

    def clipped(self) -> "Action":
        return Action(float(np.clip(self.steer, -1.0, 1.0)), float(np.clip(self.accel, 0.0, 1.0)),
                      float(np.clip(self.brake, 0.0, 1.0)))

    def as_array(self) -> np.ndarray:
        return np.array([self.steer, self.accel, self.brake], dtype=np.float64)

    @classmethod
    def from_array(cls, a) -> "Action":
        a = np.asarray(a, dtype=np.float64).reshape(3)
        return cls(float(a[0]), float(a[1]), float(a[2]))
