"""Box overlays (Liu and Wang, Figures 9-11; DeepDriving's visualiser): the camera frame beside a top-down view of
the lanes around the host car, the ground truth as filled boxes and the estimate as outlines.

- truth: host car filled red, rotated by the true angle; other cars filled yellow (gap under 60 m);
- estimate: host car outlined green, placed from the predicted toMarking indicators; other cars outlined
  purple, placed in lanes by the predicted dist_* (under 50 m);
- dashed markings between lanes, solid edges; an error bar per indicator under the camera frame; which system
  (in-lane, on-marking, both) placed the estimate, and where the lane came from.

Pure drawing on numpy arrays (OpenCV): used offline on datasets and live on closed-loop runs alike.
Images are RGB throughout.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from core.worlds.highway import (
    EDGE_MARKING,
    GAP_MAX,
    IN_LANE_SPAN,
    INDEX,
    NEIGHBOUR_LANE,
    ON_MARKING_M,
    PAPER_INDICATORS,
    REAR,
    lane_centres,
    markings,
)

PX_PER_M = 12                  # DeepDriving's scale, both directions
CANVAS = (320, 660)            # width, height of the top-down view [px]
HOST_Y = 600                   # host car's centre row
CAR_HALF = (14, 28)            # half width, half length of a car box [px] (about 2.3 x 4.7 m)
DASH = (4.0, 10.0)             # [m] dash, period: the road's own markings (sim/highway/scenery.py)
TRUTH_RANGE = GAP_MAX          # [m] other cars drawn when their gap is under the indicators' 60 m cap
ESTIMATE_RANGE = 50.0          # [m] estimated cars drawn when under this
RIGHT = 560                    # width of the right column (camera frame x2, error bars)

RED, YELLOW, GREEN, PURPLE = (230, 30, 30), (250, 210, 0), (0, 200, 60), (170, 60, 230)
ROAD, GRASS, WHITE, TEXT = (70, 70, 74), (46, 96, 46), (240, 240, 240), (20, 20, 20)

# error bar scales: an error this large fills the bar
ERROR_SCALE = {"angle": 0.2, **{n: 2.0 for n in PAPER_INDICATORS if n.startswith("toMarking")},
               **{n: 20.0 for n in PAPER_INDICATORS + REAR if n.startswith("dist")},
               **{n: 5.0 for n in REAR if n.startswith("closing")}}   # closing speeds [m/s]


@dataclass
class HostEstimate:
    d: float | None          # [m] estimated lateral offset, None when no system is active
    angle: float             # [rad]
    system: str              # "in-lane", "on-marking", "both" or "none"
    lane_source: str         # how the lane was identified: "indicators", "lanes_left", "ambiguous"
    cars: list               # [(gap [m], d [m])] of the estimated other cars


# A network's estimate of an inactive indicator is near its inactive value, never exactly on it; each system is
# judged active by the highway declaration's thresholds between its active range and its inactive values.
MARKING_M, EDGE_LR, NEIGHBOUR_LL_RR = ON_MARKING_M, EDGE_MARKING, NEIGHBOUR_LANE


def estimate_host(est: np.ndarray, lanes: int, lane_width: float, lanes_left: float | None = None,
                  hint_d: float | None = None) -> HostEstimate:
    """Where the predicted indicators put the host car and the cars ahead of it.

    The 13 indicators are relative to the lane or marking the car is on; which one it is follows from which
    neighbours exist (an inactive LL/RR or L/R), from a predicted lanes_left when the model has one, and
    otherwise is ambiguous (Liu and Wang, section 6.5): then the lane or marking nearest `hint_d` is taken and the
    overlay says so.
    """
    est = np.asarray(est, dtype=np.float64)
    m, c = markings(lanes, lane_width), lane_centres(lanes, lane_width)
    cars: list = []
    ds, systems, sources = [], [], []
    lane = _in_lane(est, lanes, m, c, lanes_left, hint_d, cars)
    if lane is not None:
        d, src = lane[1], lane[2]
        ds.append(d)
        systems.append("in-lane")
        sources.append(src)
    marking = _on_marking(est, lanes, m, c, lanes_left, hint_d, lane, cars)
    if marking is not None:
        ds.append(marking[0])
        systems.append("on-marking")
        sources.append(marking[1])
    system = "both" if len(systems) == 2 else systems[0] if systems else "none"
    source = "ambiguous" if "ambiguous" in sources else sources[0] if sources else "indicators"
    return HostEstimate(float(np.mean(ds)) if ds else None, float(est[INDEX["angle"]]), system, source, cars)


def _in_lane(est: np.ndarray, lanes: int, m, c, lanes_left: float | None, hint_d: float | None,
             cars: list) -> tuple | None:
    """The in-lane system's estimate, None when it is inactive: (the lane k the car is in, its lateral offset,
    where the lane came from); the cars it sees ahead (its lane and the two beside) are added to `cars`."""
    in_lane = -est[INDEX["toMarking_ML"]] + est[INDEX["toMarking_MR"]] < IN_LANE_SPAN
    if not in_lane:
        return None
    left_exists = est[INDEX["toMarking_LL"]] > -NEIGHBOUR_LL_RR
    right_exists = est[INDEX["toMarking_RR"]] < NEIGHBOUR_LL_RR
    if lanes_left is not None:
        k, src = int(np.clip(round(lanes_left), 0, lanes - 1)), "lanes_left"
    elif not left_exists or lanes == 1:
        k, src = 0, "indicators"
    elif not right_exists:
        k, src = lanes - 1, "indicators"
    elif lanes == 3:
        k, src = 1, "indicators"
    else:  # four lanes, both neighbours: lane 1 or lane 2
        options = [1, 2] if lanes >= 4 else [0]
        k = min(options, key=lambda i: abs(c[i] - (hint_d if hint_d is not None else 0.0)))
        src = "ambiguous"
    d = ((est[INDEX["toMarking_ML"]] + m[k]) + (est[INDEX["toMarking_MR"]] + m[k + 1])) / 2
    for name, lane in (("dist_LL", k - 1), ("dist_MM", k), ("dist_RR", k + 1)):
        if 0 <= lane < lanes and est[INDEX[name]] < ESTIMATE_RANGE:
            cars.append((float(est[INDEX[name]]), float(c[lane])))
    return k, d, src


def _on_marking(est: np.ndarray, lanes: int, m, c, lanes_left: float | None, hint_d: float | None,
                in_lane: tuple | None, cars: list) -> tuple[float, str] | None:
    """The on-marking system's estimate, None when it is inactive: (the car's lateral offset, where the marking
    came from), the in-lane estimate (`in_lane`, when active) saying which lane's marking it is; the cars it sees
    ahead in the lanes either side are added to `cars` unless the in-lane system saw them already."""
    if not abs(est[INDEX["toMarking_M"]]) < MARKING_M:
        return None
    mv = est[INDEX["toMarking_M"]]
    left_marking, right_marking = est[INDEX["toMarking_L"]] > -EDGE_LR, est[INDEX["toMarking_R"]] < EDGE_LR
    if not left_marking:
        j, src = 0, "indicators"
    elif not right_marking:
        j, src = lanes, "indicators"
    elif lanes == 1:  # both edges read as present (a poor estimate): the one nearer its inactive value
        j = 0 if abs(est[INDEX["toMarking_L"]] + EDGE_LR) < abs(est[INDEX["toMarking_R"]] - EDGE_LR) else 1
        src = "indicators"
    elif lanes == 2:
        j, src = 1, "indicators"
    elif in_lane is not None:  # the in-lane estimate says which lane; the sign of M says which of its markings
        k = in_lane[0]
        j, src = (k if mv <= 0 else k + 1), in_lane[2]
    elif lanes_left is not None:
        lane = int(np.clip(round(lanes_left), 0, lanes - 1))
        j, src = (lane if mv <= 0 else lane + 1), "lanes_left"
    else:
        inner = list(range(1, lanes))
        j = min(inner, key=lambda i: abs(m[i] - (hint_d if hint_d is not None else 0.0)))
        src = "ambiguous"
    j = int(np.clip(j, 0, lanes))
    parts = [mv + m[j]]
    if j >= 1 and left_marking:
        parts.append(est[INDEX["toMarking_L"]] + m[j - 1])
    if j + 1 <= lanes and right_marking:
        parts.append(est[INDEX["toMarking_R"]] + m[j + 1])
    for name, lane in (("dist_L", j - 1), ("dist_R", j)):
        if 0 <= lane < lanes and est[INDEX[name]] < ESTIMATE_RANGE:
            if not any(abs(cd - c[lane]) < 1e-6 for _, cd in cars):
                cars.append((float(est[INDEX[name]]), float(c[lane])))
    return float(np.mean(parts)), src


# --- drawing -----------------------------------------------------------------------------------------------------
def _x(d: float) -> float:
    return CANVAS[0] / 2 - PX_PER_M * d


def _y(gap: float) -> float:
    return HOST_Y - PX_PER_M * gap


def _box(cx: float, cy: float, angle: float) -> np.ndarray:
    """Corners of a car box centred at (cx, cy) px; angle is the indicator (track minus car yaw), so a car
    turned left of the road (negative angle) leans left on screen."""
    hw, hl = CAR_HALF
    corners = np.array([[-hw, -hl], [hw, -hl], [hw, hl], [-hw, hl]], dtype=np.float64)
    ca, sa = math.cos(angle), math.sin(angle)
    rot = np.array([[ca, -sa], [sa, ca]])
    return (corners @ rot.T + [cx, cy]).round().astype(np.int32)


def draw_topdown(lanes: int, lane_width: float, ego_s: float, ego_d: float, angle: float, cars,
                 estimate: HostEstimate | None) -> np.ndarray:
    """The 320x660 top-down view. cars: (n, 2) true (gap [m], d [m]) of the other cars."""
    w, h = CANVAS
    m = markings(lanes, lane_width)
    x0, x1 = int(round(_x(m[0]))), int(round(_x(m[-1])))
    row = np.empty((w, 3), np.uint8)
    row[:] = GRASS
    row[x0:x1] = ROAD
    img = np.empty((h, w, 3), np.uint8)
    img[:] = row    # one row broadcast down: filling with a colour triple directly took 3 ms, this 0.07
    for mj in (m[0], m[-1]):
        cv2.line(img, (int(round(_x(mj))), 0), (int(round(_x(mj))), h), WHITE, 2)
    dash, period = DASH
    s_top, s_bottom = ego_s + HOST_Y / PX_PER_M, ego_s - (h - HOST_Y) / PX_PER_M
    first = math.floor(s_bottom / period) * period
    for s in np.arange(first, s_top + period, period):
        y_a, y_b = _y(s - ego_s), _y(s + dash - ego_s)
        for mj in m[1:-1]:
            xx = int(round(_x(mj)))
            cv2.line(img, (xx, int(round(y_a))), (xx, int(round(y_b))), WHITE, 2)
    for gap, d in np.asarray(cars, dtype=np.float64).reshape(-1, 2):
        if -(h - HOST_Y) / PX_PER_M - 3 < gap < TRUTH_RANGE:
            cv2.fillConvexPoly(img, _box(_x(d), _y(gap), 0.0), YELLOW)
    cv2.fillConvexPoly(img, _box(_x(ego_d), HOST_Y, angle), RED)
    if estimate is not None:
        for gap, d in estimate.cars:
            cv2.polylines(img, [_box(_x(d), _y(gap), 0.0)], True, PURPLE, 2)
        if estimate.d is not None:
            cv2.polylines(img, [_box(_x(estimate.d), HOST_Y, estimate.angle)], True, GREEN, 2)
    return img


Extra = Sequence[tuple[str, float, float]]   # (label, truth, estimate or NaN) rows after the paper's 13


def draw_error_bars(truth: np.ndarray, est: np.ndarray | None, size=(RIGHT, 240), extra: Extra = ()) -> np.ndarray:
    """One row per paper indicator: the true value, the estimate and a bar of |estimate - truth| against its
    scale (angle 0.2 rad, markings 2 m, gaps 20 m). Without an estimate (the oracle) the rows hold the truth.
    `extra` rows (e.g. the cars beside and behind) follow; an estimate of NaN there is one the model lacks."""
    w, h = size
    img = np.full((h, w, 3), 250, np.uint8)
    names = PAPER_INDICATORS
    row = (h - 22) / (len(names) + len(extra))
    font, scale = cv2.FONT_HERSHEY_SIMPLEX, 0.38
    heads = (("truth", 110), ("estimate", 170), ("|error|", 250)) if est is not None else (("truth", 110),)
    for text, x in heads:
        cv2.putText(img, text, (x, 13), font, scale, TEXT, 1, cv2.LINE_AA)
    for i, name in enumerate(names):
        y = int(20 + i * row)
        t = float(truth[INDEX[name]])
        fmt = (lambda v: f"{v:.3f}") if name == "angle" else (lambda v: f"{v:.2f}")
        cv2.putText(img, name, (6, y + 11), font, scale, TEXT, 1, cv2.LINE_AA)
        cv2.putText(img, fmt(t), (110, y + 11), font, scale, TEXT, 1, cv2.LINE_AA)
        if est is None:
            continue
        e = float(est[INDEX[name]])
        err = abs(e - t)
        cv2.putText(img, fmt(e), (170, y + 11), font, scale, TEXT, 1, cv2.LINE_AA)
        cv2.putText(img, fmt(err), (250, y + 11), font, scale, TEXT, 1, cv2.LINE_AA)
        _bar(img, y, row, err / ERROR_SCALE[name])
    for i, (name, t, e) in enumerate(extra):
        y = int(20 + (len(names) + i) * row)
        cv2.putText(img, name, (6, y + 11), font, scale, TEXT, 1, cv2.LINE_AA)
        cv2.putText(img, f"{t:.2f}", (110, y + 11), font, scale, TEXT, 1, cv2.LINE_AA)
        if est is None or not np.isfinite(e):
            continue
        cv2.putText(img, f"{e:.2f}", (170, y + 11), font, scale, TEXT, 1, cv2.LINE_AA)
        cv2.putText(img, f"{abs(e - t):.2f}", (250, y + 11), font, scale, TEXT, 1, cv2.LINE_AA)
        _bar(img, y, row, abs(e - t) / ERROR_SCALE.get(name, 1.0))
    return img


def _bar(img: np.ndarray, y: int, row: float, share: float) -> None:
    """An error bar filled to `share` of its scale: green below a quarter, orange below three quarters, red."""
    frac = min(1.0, share)
    colour = (60, 160, 60) if frac < 0.25 else (230, 160, 0) if frac < 0.75 else (220, 40, 40)
    cv2.rectangle(img, (310, y + 2), (310 + int(240 * frac), y + int(row) - 3), colour, -1)
    cv2.rectangle(img, (310, y + 2), (550, y + int(row) - 3), (180, 180, 180), 1)


def compose(frame: np.ndarray, truth: np.ndarray, estimate: np.ndarray | None, lanes: int, lane_width: float,
            ego_s: float, ego_d: float, cars, title: str = "", lanes_left: float | None = None,
            label: str = "estimate", extra: Extra = ()) -> np.ndarray:
    """The whole overlay (RGB, 880x660): top-down view | camera frame over the error bars.

    truth/estimate: the 14 indicators (estimate None draws the truth alone); cars: true (gap, d) pairs; extra:
    more rows of error bars (draw_error_bars)."""
    host = None if estimate is None else estimate_host(estimate, lanes, lane_width, lanes_left, hint_d=ego_d)
    top = draw_topdown(lanes, lane_width, ego_s, ego_d, float(truth[INDEX["angle"]]), cars, host)
    cam = cv2.resize(frame, (RIGHT, int(RIGHT * frame.shape[0] / frame.shape[1])), interpolation=cv2.INTER_NEAREST)
    cam = cam[:420] if cam.shape[0] >= 420 else np.vstack([cam, np.zeros((420 - cam.shape[0], RIGHT, 3), np.uint8)])
    bars = draw_error_bars(truth, estimate, extra=extra)
    right = np.vstack([cam, bars])
    out = np.hstack([top, right])
    lines = [title] if title else []
    if host is not None:
        lines.append(f"{label}: {host.system}" + (f", lane from {host.lane_source}" if host.system != "none" else ""))
    else:
        lines.append("ground truth")
    if lines:  # on a dark band, so it reads over sky and road alike
        width = max(cv2.getTextSize(t, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)[0][0] for t in lines)
        band = out[0:8 + 16 * len(lines), CANVAS[0]:CANVAS[0] + width + 14]
        band[:] = (band * 0.35).astype(np.uint8)
    for i, text in enumerate(lines):
        cv2.putText(out, text, (CANVAS[0] + 7, 16 + 16 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.45, WHITE, 1, cv2.LINE_AA)
    legend = [("truth host", RED), ("truth cars", YELLOW), ("estimate host", GREEN), ("estimate cars", PURPLE)]
    for i, (text, colour) in enumerate(legend):
        y = 12 + 14 * i
        cv2.rectangle(out, (6, y - 8), (16, y), colour, -1)
        cv2.putText(out, text, (20, y), cv2.FONT_HERSHEY_SIMPLEX, 0.35, WHITE, 1, cv2.LINE_AA)
    return out


def mean_normalised_error(truth: np.ndarray, estimate: np.ndarray) -> float:
    """Mean absolute error over the paper's 13 indicators, each divided by its error-bar scale: the ranking
    behind `--select worst` (so angle and gaps weigh alike)."""
    return float(np.mean([abs(estimate[INDEX[n]] - truth[INDEX[n]]) / ERROR_SCALE[n] for n in PAPER_INDICATORS]))

