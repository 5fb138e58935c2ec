"""The highway world's declaration: DeepDriving's affordance indicators, the highway's truth record, its camera
and its steer/accel/brake action (docs/affordances.md defines every indicator; docs/controller.md the action).

This module is the single owner of these facts. sim (ground truth), controller (the Chen controller),
perception (overlays, the Table 3 report) and the bridge read them from here; it imports only numpy and the
declaration types.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.declaration import Camera, Column, Control, Label, Quantity, WorldDeclaration

# --- the indicators ----------------------------------------------------------------------------------------------
# Canonical order: Liu and Wang's Table 1 (DeepDriving's 13), then `fast`.
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
GAPS: tuple[str, ...] = ("dist_LL", "dist_MM", "dist_RR", "dist_L", "dist_R")

GAP_MAX = 60.0       # [m] gap of an active, existing lane with no car ahead within it
GAP_INACTIVE = 75.0  # [m] gap of an inactive system or of a lane that does not exist
# [m] a neighbour lane counts as occupied by a car ahead closer than this: the Chen controller's rule 1, and the
# frames a trainer may emphasise (those on which its lane changes are decided)
NEIGHBOUR_OCCUPIED = 20.0

INACTIVE: dict[str, float] = {
    "toMarking_LL": -9.5, "toMarking_ML": -5.5, "toMarking_MR": 5.5, "toMarking_RR": 9.5,
    "dist_LL": GAP_INACTIVE, "dist_MM": GAP_INACTIVE, "dist_RR": GAP_INACTIVE,
    "toMarking_L": -7.0, "toMarking_M": 3.5, "toMarking_R": 7.0,
    "dist_L": GAP_INACTIVE, "dist_R": GAP_INACTIVE,
}

# --- beside and behind: the extended label set (ours, beyond DeepDriving; docs/affordances.md) ------------------
# The 13 see only cars ahead. For the lanes left and right of the host car's lane k (= lanes_left), the nearest car
# alongside or behind it: the bumper-to-bumper gap along the centreline (0 while the car overlaps the host's length)
# and how fast it closes in (its speed minus the host's). A lane that does not exist, or holds no such car within
# REAR_RANGE, reads REAR_RANGE and a closing speed of 0: nothing there can reach the host.
REAR: tuple[str, ...] = ("dist_LB", "dist_RB", "closing_LB", "closing_RB")
REAR_RANGE = 100.0      # [m] rear gaps are measured up to this; also their inactive value
CLOSING_INACTIVE = 0.0  # [m/s] closing speed when no car is within REAR_RANGE or the lane does not exist
HOST_LENGTH = 4.6       # [m] the host car's body (sim/highway/vehicle.py VehicleParams.length, SUMO's host)

# Named label sets (`train --targets NAME`): the paper's 13 stay the default; `extended` adds `fast`, `lanes_left`
# and the four above. Names and order are fixed once published: models trained on a set depend on them.
LABEL_SETS: dict[str, tuple[str, ...]] = {
    "paper": PAPER_INDICATORS,
    "extended": INDICATORS + ("lanes_left",) + REAR,
}

# DeepDriving's affine maps to about [0.1, 0.9]: normalised = value * scale + offset. lanes_left is ours
# (0..3 -> 0.1..0.7); angle is additionally clipped to [0, 1].
NORMALISATION: dict[str, tuple[float, float]] = {
    "angle": (1 / 1.1, 0.5),
    "toMarking_LL": (0.14545, 1.48181), "toMarking_ML": (0.16, 0.98),
    "toMarking_MR": (0.16, 0.02), "toMarking_RR": (0.14545, -0.48181),
    "dist_LL": (1 / 95, 0.12), "dist_MM": (1 / 95, 0.12), "dist_RR": (1 / 95, 0.12),
    "toMarking_L": (0.17778, 1.34445), "toMarking_M": (0.14545, 0.39091), "toMarking_R": (0.17778, -0.34445),
    "dist_L": (1 / 95, 0.12), "dist_R": (1 / 95, 0.12),
    "fast": (0.6, 0.2),
    "lanes_left": (0.2, 0.1),
    # ours: rear gaps 0..100 m and closing speeds -20..20 m/s both to 0.1..0.9
    "dist_LB": (0.8 / REAR_RANGE, 0.1), "dist_RB": (0.8 / REAR_RANGE, 0.1),
    "closing_LB": (0.02, 0.5), "closing_RB": (0.02, 0.5),
}

# A network's estimate of an inactive indicator lands near its inactive value, never on it. These thresholds lie
# between each system's active range and its inactive values; the controller, the expert and the overlays all
# judge an estimate by them.
IN_LANE_SPAN = 5.5     # [m] -toMarking_ML + toMarking_MR below this: the in-lane system is active (4 vs 11)
NEIGHBOUR_LANE = 8.0   # [m] |toMarking_LL|, |toMarking_RR| below this: a lane exists on that side (vs 9.5)
EDGE_MARKING = 6.5     # [m] |toMarking_L|, |toMarking_R| beyond this: no marking on that side (vs 7)
ON_MARKING_M = 2.75    # [m] |toMarking_M| below this: the on-marking system is active (at most 2 vs 3.5)

# --- the host car and the road -----------------------------------------------------------------------------------
STEER_LOCK_RAD = 0.541052   # full lock of the host car: steer = 1 means this front-wheel angle, to the LEFT
FRAME = (210, 280)          # (rows, columns) of the camera frame, as DeepDriving's TORCS frames
MAX_LANES = 4
LANE_WIDTH = 4.0            # [m] default lane width


def markings(lanes: int, lane_width: float) -> np.ndarray:
    """Lateral offsets [m] of the markings m_j = (N/2 - j) w, j = 0..N: the left edge first (d positive left)."""
    return (lanes / 2 - np.arange(lanes + 1)) * lane_width


def lane_centres(lanes: int, lane_width: float) -> np.ndarray:
    """Lateral offsets [m] of the lane centres c_k = (N/2 - k - 1/2) w, k = 0..N-1: the leftmost lane first."""
    return (lanes / 2 - np.arange(lanes) - 0.5) * lane_width


def label_set(fast: bool = False, lanes_left: bool = False) -> tuple[str, ...]:
    """The regression targets of a model: the paper's 13, optionally `fast` and `lanes_left`."""
    return PAPER_INDICATORS + (("fast",) if fast else ()) + (("lanes_left",) if lanes_left else ())


def indicators_to_dict(values) -> dict[str, float]:
    """The 14 indicators as a {DeepDriving name: value} mapping, in canonical order."""
    values = np.asarray(values, dtype=np.float64)
    if values.shape != (len(INDICATORS),):
        raise ValueError(f"expected {len(INDICATORS)} indicators, got shape {values.shape}")
    return {name: float(v) for name, v in zip(INDICATORS, values)}


@dataclass(frozen=True)
class Action:
    """A TORCS-style driving command.

    steer: [-1, 1], positive turns left, 1 = full lock (STEER_LOCK_RAD). accel, brake: [0, 1] pedal fractions.
    """

    steer: float = 0.0
    accel: float = 0.0
    brake: float = 0.0

    def clipped(self) -> Action:
        return Action(float(np.clip(self.steer, -1.0, 1.0)), float(np.clip(self.accel, 0.0, 1.0)),
                      float(np.clip(self.brake, 0.0, 1.0)))

    def as_array(self) -> np.ndarray:
        return np.array([self.steer, self.accel, self.brake], dtype=np.float64)

    @classmethod
    def from_array(cls, a) -> Action:
        a = np.asarray(a, dtype=np.float64).reshape(3)
        return cls(float(a[0]), float(a[1]), float(a[2]))


# --- the declaration ---------------------------------------------------------------------------------------------
_MEANING = {
    "angle": "track tangent yaw minus the host car's yaw", "fast": "1 on a straight that goes on > 60 m",
    "toMarking_LL": "d minus the left marking of the lane to the left",
    "toMarking_ML": "d minus the left marking of the current lane",
    "toMarking_MR": "d minus the right marking of the current lane",
    "toMarking_RR": "d minus the right marking of the lane to the right",
    "dist_LL": "gap to the car ahead in the lane to the left", "dist_MM": "gap to the car ahead in this lane",
    "dist_RR": "gap to the car ahead in the lane to the right",
    "toMarking_L": "d minus the marking left of the one the car is on",
    "toMarking_M": "d minus the marking the car is on",
    "toMarking_R": "d minus the marking right of the one the car is on",
    "dist_L": "gap to the car ahead in the lane left of the marking",
    "dist_R": "gap to the car ahead in the lane right of the marking",
    "dist_LB": "bumper gap to the nearest car alongside or behind in the lane to the left (0: alongside)",
    "dist_RB": "bumper gap to the nearest car alongside or behind in the lane to the right (0: alongside)",
    "closing_LB": "that car's speed minus the host's (positive: it closes in), lane to the left",
    "closing_RB": "that car's speed minus the host's (positive: it closes in), lane to the right",
}
_REAR_INACTIVE = {"dist_LB": REAR_RANGE, "dist_RB": REAR_RANGE, "closing_LB": CLOSING_INACTIVE,
                  "closing_RB": CLOSING_INACTIVE}


def _unit(name: str) -> str:
    return "rad" if name == "angle" else "0/1" if name == "fast" else "m/s" if name.startswith("closing") else "m"


HIGHWAY = WorldDeclaration(
    name="highway",
    title="multi-lane highway with SUMO traffic (DeepDriving's TORCS set-up)",
    dt=0.1,
    cameras=(Camera("front", *FRAME),),
    labels=tuple(Label(n, _unit(n), _MEANING[n], *NORMALISATION[n], clip=(0.0, 1.0) if n == "angle" else None,
                       inactive=INACTIVE.get(n)) for n in INDICATORS)
    + (Label("lanes_left", "count", "lanes to the left of the host car's lane", *NORMALISATION["lanes_left"]),)
    + tuple(Label(n, _unit(n), _MEANING[n], *NORMALISATION[n], inactive=_REAR_INACTIVE[n]) for n in REAR),
    truth=tuple(Quantity(n, _unit(n), "indicator (docs/affordances.md)", "f32") for n in INDICATORS) + (
        Quantity("lanes_left", "count", "lanes to the left of the host car's lane", "i8"),
        Quantity("lanes", "count", "lanes of the road", "i8"),
        Quantity("lane_width", "m", "lane width", "f32"),
        Quantity("speed", "m/s", "host car's speed", "f32"),
        Quantity("in_lane", "0/1", "1: the in-lane system is active", "bool"),
        Quantity("on_marking", "0/1", "1: the on-marking system is active", "bool"),
        Quantity("x", "m", "host car's position, world frame", "f64"),
        Quantity("y", "m", "host car's position, world frame", "f64"),
        Quantity("yaw", "rad", "host car's heading, counter-clockwise", "f64"),
        Quantity("s", "m", "arc length along the track", "f64"),
        Quantity("d", "m", "lateral offset from the centreline, positive left", "f64"),
        Quantity("collision", "0/1", "1: the host car touches another car", "bool"),
        Quantity("off_road", "0/1", "1: the host car's centre is beyond a road edge", "bool"),
    ) + tuple(Quantity(n, _unit(n), f"{_MEANING[n]} (docs/affordances.md)", "f32") for n in REAR),
    action=(Control("steer", "-", "front wheels, +1 = full lock LEFT (0.541052 rad)", -1.0, 1.0, 0.0),
            Control("accel", "-", "throttle pedal", 0.0, 1.0, 0.0),
            Control("brake", "-", "brake pedal", 0.0, 1.0, 0.0)),
    columns=(Column("track", "str", "track reference (preset, file or procedural:SEED)"),
             Column("perturbation", "str", "what the data-collection expert did at this step"),
             Column("cars", "f32[5]*", "other cars: x, y, yaw, s, d")),
    targets=PAPER_INDICATORS,
    label_sets=tuple(LABEL_SETS.items()),
    # an agent reads the 14 indicators and its own speedometer, as the Chen controller does (docs/gymnasium.md)
    observable=INDICATORS + ("speed",),
    # the frames on which a misread gap costs a collision: a car near ahead in a neighbouring lane, in either
    # system (rule 1's occupancy: the Chen controller decides a lane change on it), or in the host's own lane (the
    # follow law brakes on it); rare in an expert's data (docs/explanation/learned-driving.md, "Decisive frames").
    # The cars behind are not decisive: a network of the rear labels emphasised on its near cars behind drives worse
    # on both design suites (docs/log/2026-11-28-night.md; the host lane's car: docs/log/2026-11-27.md)
    decisive=tuple((g, NEIGHBOUR_OCCUPIED) for g in ("dist_LL", "dist_MM", "dist_RR", "dist_L", "dist_R")),
)
