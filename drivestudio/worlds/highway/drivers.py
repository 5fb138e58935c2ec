"""The highway's drivers: the Chen controller on perception (the oracle: the exact indicators; or a trained
regressor's estimates, optionally smoothed) and the perturbed data-collection expert."""
from __future__ import annotations

import time

import numpy as np

from controller.highway import ChenController
from controller.highway.expert import PerturbedExpert
from core.worlds.highway import HIGHWAY, INDICATORS
from drivestudio.loop import Percept
from perception.history import History

ESTIMATE = tuple(HIGHWAY.estimate_names)
ESTIMATE_INDEX = {n: i for i, n in enumerate(ESTIMATE)}
_GAPS = [i for i, n in enumerate(ESTIMATE) if n.startswith("dist_")]


class ChenDriver:
    """Perception (a trained regressor, or the truth itself for the oracle: perfect perception, the upper bound
    every network is compared with) and the Chen controller. The controller is made on the first frame, when the
    lane count is known."""

    def __init__(self, predictor=None, smoothing: float = 0.0, gap_hold: float = 0.0):
        self.predictor = predictor
        self.smoothing, self.gap_hold = smoothing, gap_hold
        self.timings = {"perception": 0.0, "control": 0.0}
        self.controller = None
        self._i_speed, self._i_lanes = HIGHWAY.index("speed"), HIGHWAY.index("lanes")
        self._slots = [] if predictor is None else [(i, ESTIMATE_INDEX[n]) for i, n in
                                                    enumerate(predictor.outputs) if n in ESTIMATE_INDEX]
        self._smoothed = self._held = None
        self.history = History(predictor.instants if predictor is not None else (0,))   # a temporal model's frames

    @property
    def name(self) -> str:
        return "oracle" if self.predictor is None else self.predictor.name

    def estimate(self, percept: Percept) -> np.ndarray:
        """The estimate record (the 14 indicators and lanes_left; NaN where the model has no output)."""
        if self.predictor is None:
            est = np.full(len(ESTIMATE), np.nan)
            est[:len(INDICATORS)] = percept.record[:len(INDICATORS)]
            est[ESTIMATE_INDEX["lanes_left"]] = percept.record[HIGHWAY.index("lanes_left")]
            return est
        values = self.predictor(self.history.push(percept.frames))
        est = np.full(len(ESTIMATE), np.nan)
        for i, j in self._slots:
            est[j] = values[i]
        if self.smoothing > 0:   # exponential smoothing of the estimate (an option, docs/controller.md)
            if self._smoothed is not None:
                est = np.where(np.isfinite(self._smoothed), self.smoothing * self._smoothed +
                               (1 - self.smoothing) * est, est)
            self._smoothed = est
        if self.gap_hold > 0:   # the gaps: a car coming closer at once, one going away slowly (docs/controller.md)
            if self._held is not None:
                est[_GAPS] = np.fmin(est[_GAPS], self.gap_hold * self._held + (1 - self.gap_hold) * est[_GAPS])
            self._held = est[_GAPS].copy()
        return est

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        est = self.estimate(percept)
        t1 = time.perf_counter()
        lanes = int(percept.record[self._i_lanes])
        if self.controller is None or self.controller.lanes != lanes:
            self.controller = ChenController(lanes)
        indicators = np.nan_to_num(est[:len(INDICATORS)], nan=0.0)   # a 13-output model: fast = 0
        action = self.controller.act(indicators, float(percept.record[self._i_speed]))
        self.timings["perception"] += t1 - t0
        self.timings["control"] += time.perf_counter() - t1
        return action.as_array(), est


class ExpertDriver:
    """The data-collection expert (controller/highway/expert.py): the Chen controller on the true indicators with seeded
    perturbations; `label` names the perturbation acting on the last step."""

    name = "expert"

    def __init__(self, lanes: int, lane_width: float, seed_: int, dt: float):
        self.expert = PerturbedExpert(lanes, lane_width, seed_, dt=dt)
        self.label = "none"
        self.timings = {"control": 0.0}
        self._i_speed, self._i_d = HIGHWAY.index("speed"), HIGHWAY.index("d")

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        r = percept.record
        action, self.label = self.expert.act(r[:len(INDICATORS)], float(r[self._i_speed]), float(r[self._i_d]))
        est = np.full(len(ESTIMATE), np.nan)
        est[:len(INDICATORS)] = r[:len(INDICATORS)]
        return action.as_array(), est
