"""Exact ground-truth affordance indicators (docs/affordances.md, rule by rule).

Everything is computed from track coordinates: the host car's (s, d, heading relative to the tangent) and
the other cars' (s, d). Names, order and inactive values come from the highway's declaration
(core/worlds/highway.py).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.worlds.highway import (
    CLOSING_INACTIVE,
    GAP_INACTIVE,
    GAP_MAX,
    HIGHWAY,
    HOST_LENGTH,
    INACTIVE,
    INDEX,
    INDICATORS,
    REAR,
    REAR_RANGE,
    indicators_to_dict,
)
from sim.track import Track, wrap_angle

IN_LANE_MARGIN = 0.5           # [m] in-lane system: |d - c_k| <= w/2 - margin
MARKING_BAND = 1.0             # [m] h, on-marking half band around a marking
MARKING_BAND_TWO_LANE = 1.2    # [m] h on two-lane roads (DeepDriving's two-lane driver)
EDGE_OUTSIDE = 2.0             # [m] the edge bands reach this far outside the road
FAST_STRAIGHT = 60.0           # [m] `fast` when more straight than this lies ahead


def marking_band(lanes: int) -> float:
    return MARKING_BAND_TWO_LANE if lanes == 2 else MARKING_BAND


def lane_gaps(track: Track, ego_s: float, cars_s, cars_d) -> np.ndarray:
    """Per lane (0 = leftmost): centre-to-centre gap [m] to the nearest car strictly ahead, capped at GAP_MAX."""
    gaps = [GAP_MAX] * track.lanes
    cars_s = np.asarray(cars_s, dtype=np.float64)
    if cars_s.size:
        lanes = track.lane_of(np.asarray(cars_d, dtype=np.float64)).tolist()
        for ds, k in zip(track.gap(ego_s, cars_s).tolist(), lanes):   # a handful of cars: a loop beats numpy's calls
            if 0 < ds < gaps[k]:
                gaps[k] = ds
    return np.array(gaps)


def rear_indicators(track: Track, ego_s: float, ego_d: float, host_length: float, host_speed: float, cars_s=(),
                    cars_d=(), cars_length=(), cars_speed=()) -> np.ndarray:
    """dist_LB, dist_RB, closing_LB, closing_RB (core/worlds/highway.py REAR order): for the lanes left and right of
    the host car's lane k = lanes_left, the bumper-to-bumper gap [m] to the nearest car alongside or behind the
    host, and that car's closing speed [m/s] (its speed minus the host's).

    A car counts when it is not wholly ahead (s_car - s_host < (host_length + car_length) / 2) and its gap,
    s_host - s_car - (host_length + car_length) / 2 along the centreline, is below REAR_RANGE; the gap is 0 while
    it overlaps the host's length. Of equal gaps the faster car counts. A lane that does not exist, or holds no such
    car, reads REAR_RANGE and CLOSING_INACTIVE."""
    out = np.array([REAR_RANGE, REAR_RANGE, CLOSING_INACTIVE, CLOSING_INACTIVE])
    cars_s = np.asarray(cars_s, dtype=np.float64)
    if not cars_s.size:
        return out
    half = (host_length + np.asarray(cars_length, dtype=np.float64)) / 2
    behind = -track.gap(ego_s, cars_s) - half            # bumper gap; negative: overlapping or ahead
    near = np.flatnonzero((behind > -2 * half) & (behind < REAR_RANGE))   # -2 half: its rear at the host's front
    if not near.size:
        return out
    lanes = track.lane_of(np.asarray(cars_d, dtype=np.float64)[near]).tolist()
    gap = np.maximum(behind[near], 0.0).tolist()
    close = (np.asarray(cars_speed, dtype=np.float64)[near] - host_speed).tolist()
    k = track.lane_of(ego_d)
    for i, lane in enumerate((k - 1, k + 1)):   # no car is in a lane that does not exist
        # the least gap, then the fastest; a handful of cars: Python's min beats numpy's calls
        first = min(((g, -c) for g, c, m in zip(gap, close, lanes) if m == lane), default=None)
        if first is not None:
            out[i], out[2 + i] = first[0], -first[1]
    return out


def on_marking_index(track: Track, d: float) -> int | None:
    """The marking j whose on-marking band contains d, or None. Bands never overlap for legal lane widths."""
    h = marking_band(track.lanes)
    m = track.markings
    if m[0] - h <= d <= m[0] + EDGE_OUTSIDE:
        return 0
    if m[-1] - EDGE_OUTSIDE <= d <= m[-1] + h:
        return track.lanes
    for j in range(1, track.lanes):
        if abs(d - m[j]) <= h:
            return j
    return None


def in_lane_active(track: Track, d: float) -> bool:
    k = track.lane_of(d)
    return abs(d - track.lane_centres[k]) <= track.lane_width / 2 - IN_LANE_MARGIN


def affordances(track: Track, ego_s: float, ego_d: float, ego_heading: float, cars_s=(), cars_d=()) -> np.ndarray:
    """The 14 indicators in canonical order.

    ego_heading [rad] is the host car's yaw relative to the track tangent (counter-clockwise positive), so
    angle = -ego_heading, wrapped to (-pi, pi].
    """
    out = np.array([0.0] + [INACTIVE[n] for n in INDICATORS[1:13]] + [0.0])
    out[INDEX["angle"]] = float(wrap_angle(-ego_heading))
    gaps = lane_gaps(track, ego_s, cars_s, cars_d)
    n, m = track.lanes, track.markings

    def gap_of(lane: int) -> float:
        return float(gaps[lane]) if 0 <= lane < n else GAP_INACTIVE

    if in_lane_active(track, ego_d):
        k = track.lane_of(ego_d)
        out[INDEX["toMarking_ML"]] = ego_d - m[k]
        out[INDEX["toMarking_MR"]] = ego_d - m[k + 1]
        if k >= 1:
            out[INDEX["toMarking_LL"]] = ego_d - m[k - 1]
        if k + 2 <= n:
            out[INDEX["toMarking_RR"]] = ego_d - m[k + 2]
        out[INDEX["dist_LL"]] = gap_of(k - 1)
        out[INDEX["dist_MM"]] = gap_of(k)
        out[INDEX["dist_RR"]] = gap_of(k + 1)

    j = on_marking_index(track, ego_d)
    if j is not None:
        out[INDEX["toMarking_M"]] = ego_d - m[j]
        if j >= 1:
            out[INDEX["toMarking_L"]] = ego_d - m[j - 1]
        if j + 1 <= n:
            out[INDEX["toMarking_R"]] = ego_d - m[j + 1]
        out[INDEX["dist_L"]] = gap_of(j - 1)  # the lane left of marking j is lane j-1
        out[INDEX["dist_R"]] = gap_of(j)      # the lane right of marking j is lane j

    out[INDEX["fast"]] = 1.0 if track.straight_ahead(ego_s) > FAST_STRAIGHT else 0.0
    return out


@dataclass
class GroundTruth:
    """Everything the world knows about one instant, for labels, controllers and overlays.

    indicators: the 14 in canonical order. ego: [x, y, yaw, s, d] (m, m, rad, m, m). cars: (n, 5) with the
    same columns for every other car. lanes_left: lanes to the left of the host car's lane (Liu and Wang, section 6.5).
    rear: dist_LB, dist_RB, closing_LB, closing_RB (ours: the cars beside and behind, docs/affordances.md).
    """

    indicators: np.ndarray
    lanes_left: int
    lanes: int
    lane_width: float
    speed: float                      # [m/s]
    in_lane: bool
    on_marking: bool
    ego: np.ndarray
    cars: np.ndarray = field(default_factory=lambda: np.zeros((0, 5)))
    rear: np.ndarray = field(default_factory=lambda: np.array([REAR_RANGE, REAR_RANGE, CLOSING_INACTIVE,
                                                               CLOSING_INACTIVE]))

    def as_dict(self) -> dict:
        return {**indicators_to_dict(self.indicators), "lanes_left": self.lanes_left,
                **{n: float(v) for n, v in zip(REAR, self.rear)}, "lanes": self.lanes,
                "lane_width": self.lane_width, "speed": self.speed, "in_lane": self.in_lane,
                "on_marking": self.on_marking, "ego": self.ego.tolist(), "cars": self.cars.tolist()}


def ground_truth(track: Track, ego: np.ndarray, ego_heading: float, speed: float, cars: np.ndarray,
                 cars_length, cars_speed, host_length: float = HOST_LENGTH) -> GroundTruth:
    """Assemble the full ground truth from poses ([x, y, yaw, s, d] rows), the host car's relative heading, speed
    [m/s] and length [m], and the other cars' lengths [m] and speeds [m/s]."""
    cars = np.asarray(cars, dtype=np.float64).reshape(-1, 5)
    s, d = float(ego[3]), float(ego[4])
    rear = rear_indicators(track, s, d, host_length, float(speed), cars[:, 3], cars[:, 4], cars_length, cars_speed)
    return GroundTruth(
        indicators=affordances(track, s, d, ego_heading, cars[:, 3], cars[:, 4]),
        lanes_left=track.lane_of(d), lanes=track.lanes, lane_width=track.lane_width, speed=float(speed),
        in_lane=bool(in_lane_active(track, d)), on_marking=on_marking_index(track, d) is not None,
        ego=np.asarray(ego, dtype=np.float64), cars=cars, rear=rear)


# the truth record after the 14 indicators, in the declaration's order (checked at import); the rear labels came
# last, so that every field before them kept its position
_RECORD_TAIL = ("lanes_left", "lanes", "lane_width", "speed", "in_lane", "on_marking", "x", "y", "yaw", "s", "d",
                "collision", "off_road") + REAR
assert HIGHWAY.truth_names == INDICATORS + _RECORD_TAIL, \
    "sim/highway/truth.py packs the highway's truth record by position"


def truth_record(truth: GroundTruth, collision: bool, off_road: bool) -> np.ndarray:
    """The highway's truth record (float64, HIGHWAY.truth order): what the bridge carries and datasets store."""
    out = np.empty(len(INDICATORS) + len(_RECORD_TAIL))
    out[:len(INDICATORS)] = truth.indicators
    out[len(INDICATORS):] = (truth.lanes_left, truth.lanes, truth.lane_width, truth.speed, truth.in_lane,
                             truth.on_marking, *truth.ego, collision, off_road, *truth.rear)
    return out
