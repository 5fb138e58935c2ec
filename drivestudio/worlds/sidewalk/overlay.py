"""drivestudio overlay for the sidewalk world: both cameras of a recorded step beside the truth and the estimate
of its steering and motor over the next 10 steps (the data moment's targets).

The truth of a step's future commands is in the record when the overlay verb puts it there (record["targets"],
{output: value}); otherwise the step's own command stands for all ten.
"""
from __future__ import annotations

import cv2
import numpy as np

from core.worlds.sidewalk import HORIZON, MODES, OPERATIONS

PANEL = 200   # [px] width of the plots beside the cameras


def _future(record: dict, estimate: dict | None, label: str) -> tuple[np.ndarray, np.ndarray | None]:
    """(truth, estimate) of (steer, motor) x HORIZON future values."""
    targets = record.get("targets") or {}
    truth = np.array([[targets.get(f"{n}+{k}", record[n]) for k in range(1, HORIZON + 1)] for n in ("steer", "motor")],
                     dtype=np.float64)
    if estimate is None:
        return truth, None
    est = np.array([[estimate.get(f"{n}+{k}", np.nan) for k in range(1, HORIZON + 1)] for n in ("steer", "motor")],
                   dtype=np.float64)
    return truth, est


def _plot(h: int, truth: np.ndarray, est: np.ndarray | None, title: str) -> np.ndarray:
    """Truth (filled dots) and estimate (rings) of one label over the horizon, 0 at the bottom, 1 at the top."""
    img = np.full((h, PANEL, 3), 245, np.uint8)
    top, bottom, left, right = 22, h - 8, 10, PANEL - 10
    cv2.rectangle(img, (left, top), (right, bottom), (180, 180, 180), 1)
    mid = top + (bottom - top) // 2
    cv2.line(img, (left, mid), (right, mid), (210, 210, 210), 1)
    cv2.putText(img, title, (left, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (40, 40, 40), 1, cv2.LINE_AA)

    def pt(k, v):
        x = left + (k + 0.5) * (right - left) / HORIZON
        y = bottom - float(np.clip(v, 0, 1)) * (bottom - top)
        return int(round(x)), int(round(y))
    for k, v in enumerate(truth):
        cv2.circle(img, pt(k, v), 4, (30, 140, 30), -1, cv2.LINE_AA)
    if est is not None:
        for k, v in enumerate(est):
            if np.isfinite(v):
                cv2.circle(img, pt(k, v), 5, (200, 40, 40), 1, cv2.LINE_AA)
    return img


def overlay(images, record: dict, estimate: dict | None, label: str) -> np.ndarray:
    left, right = images[0], images[1]
    h = left.shape[0]
    truth, est = _future(record, estimate, label)
    half = h // 2
    plots = np.concatenate([_plot(half, truth[0], None if est is None else est[0], "steer: truth (dots), " + label),
                            _plot(h - half, truth[1], None if est is None else est[1], "motor, next 10 steps")], axis=0)
    row = np.concatenate([left, right, plots], axis=1)
    bar = np.full((22, row.shape[1], 3), 30, np.uint8)
    text = (f"episode {record.get('episode')} step {record.get('step')}  {record.get('path', '')}  "
            f"{MODES[int(record['behaviour'])]}  {OPERATIONS[int(record['operation'])]}  "
            f"{float(record['speed']):.2f} m/s")
    cv2.putText(bar, text, (6, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (235, 235, 235), 1, cv2.LINE_AA)
    return np.concatenate([row, bar], axis=0)


def overlay_error(record: dict, estimate: dict | None) -> float:
    """Mean absolute error of the estimate over the 20 future values (larger: worse)."""
    truth, est = _future(record, estimate, "")
    if est is None:
        return 0.0
    err = np.abs(est - truth)
    return float(np.nanmean(err)) if np.isfinite(err).any() else 0.0
