"""Wiring for the highway's overlays: from its observations or a dataset's records to
perception.highway.overlay.compose."""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from core.worlds.highway import REAR
from perception.highway.overlay import compose
from sim.track import Track, TrackError, load_track


@lru_cache(maxsize=64)
def track_of(ref: str, lanes: int) -> Track:
    """The track a dataset record names (datasets before the `track` column held references used names)."""
    try:
        return load_track(ref, lanes=lanes)
    except TrackError:
        if ref.startswith("procedural-"):
            return load_track("procedural:" + ref.split("-", 1)[1], lanes=lanes)
        raise


def car_gaps(track: Track, ego_s: float, cars: np.ndarray) -> np.ndarray:
    """(n, 2): along-track gap [m] and lateral offset d [m] of each other car ([x, y, yaw, s, d] rows)."""
    cars = np.asarray(cars, dtype=np.float64).reshape(-1, 5)
    return np.stack([track.gap(ego_s, cars[:, 3]), cars[:, 4]], axis=1) if len(cars) else np.zeros((0, 2))


def rear_rows(truth, estimate) -> list[tuple[str, float, float]]:
    """Error-bar rows of the cars beside and behind: (name, truth, estimate or NaN), for the labels the truth has
    (a dataset recorded before them has none)."""
    est = np.full(len(REAR), np.nan) if estimate is None else np.asarray(estimate, dtype=np.float64)
    return [(n, float(t), float(e)) for n, t, e in zip(REAR, truth, est) if t is not None and np.isfinite(t)]


def overlay_observation(obs, estimate: np.ndarray | None, track: Track, title: str = "",
                        lanes_left: float | None = None, label: str = "estimate",
                        rear: np.ndarray | None = None) -> np.ndarray:
    """The overlay of a world's observation; estimate: the 14 indicators, rear: the 4 rear labels (NaN: none)."""
    t = obs.truth
    return compose(obs.frame, t.indicators, estimate, t.lanes, t.lane_width, float(t.ego[3]), float(t.ego[4]),
                   car_gaps(track, t.ego[3], t.cars), title, lanes_left, label, rear_rows(t.rear, rear))


def overlay_record(image: np.ndarray, record: dict, truth: np.ndarray, estimate: np.ndarray | None,
                   title: str = "", lanes_left: float | None = None, label: str = "estimate",
                   rear: np.ndarray | None = None) -> np.ndarray:
    track = track_of(record["track"], int(record["lanes"]))
    return compose(image, truth, estimate, int(record["lanes"]), float(record["lane_width"]), float(record["s"]),
                   float(record["d"]), car_gaps(track, record["s"], record["cars"]), title, lanes_left, label,
                   rear_rows([record.get(n) for n in REAR], rear))
