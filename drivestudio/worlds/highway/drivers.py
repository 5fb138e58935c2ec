"""The highway's drivers: the Chen controller on perception (the oracle: the exact indicators; or a trained
regressor's estimates, optionally filtered), the extended oracle (the lookout controller on the exact extended
labels) and the perturbed data-collection expert."""
from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from controller.highway import ChenController
from controller.highway.chen import KEEP
from controller.highway.expert import PerturbedExpert
from controller.highway.lookout import NOTHING_BEHIND, LookoutController, LookoutParams
from core.worlds.highway import HIGHWAY, INDICATORS, REAR
from drivestudio.driver_spec import DriverSpec
from drivestudio.loop import Percept
from drivestudio.worlds.highway.filters import ESTIMATE, Filter, make_filters
from perception.history import History

ESTIMATE_INDEX = {n: i for i, n in enumerate(ESTIMATE)}
_TRUTH_OF_ESTIMATE = [HIGHWAY.index(n) for n in ESTIMATE]   # every label is a field of the truth record
_REAR = [ESTIMATE_INDEX[n] for n in REAR]

# the drivers on exact labels, by --model name: whether each looks beside and behind (controller/highway/lookout.py)
ORACLES = {"oracle": False, "oracle-extended": True}


def reads_behind(outputs) -> bool:
    """Whether a model estimates the cars beside and behind (the four rear labels of the extended set): such a
    model drives with the lookout controller, as the extended oracle does on the exact labels; any other with
    Chen's, which sees only ahead."""
    return set(REAR) <= set(outputs)


def make_controller(lanes: int, lookout: bool, exact: bool = False) -> ChenController:
    """The controller of a driver: the Chen controller, or the lookout controller (rules L1-L4 on top, and L5 on
    exact labels: the extended oracle's, controller/highway/lookout.py)."""
    if not lookout:
        return ChenController(lanes)
    return LookoutController(lanes, lookout=LookoutParams(stop_in_time=exact))


def act_on(controller: ChenController, estimate: np.ndarray, speed: float):
    """The controller's command for an estimate record: the 14 indicators (NaN as 0: a 13-output model has no
    `fast`) and, for the lookout, the rear labels (NaN: nothing known beside or behind)."""
    indicators = np.nan_to_num(estimate[:len(INDICATORS)], nan=0.0)
    if isinstance(controller, LookoutController):
        rear = np.where(np.isfinite(estimate[_REAR]), estimate[_REAR], NOTHING_BEHIND)
        return controller.act(indicators, speed, rear)
    return controller.act(indicators, speed)


class ChenDriver:
    """Perception (a trained regressor, or the truth itself for the oracle: perfect perception, the upper bound
    every network is compared with), the estimate filters of its driver spec (drivestudio/worlds/highway/filters.py)
    and the Chen controller. The controller is made on the first frame, when the lane count is known."""

    def __init__(self, predictor=None, lookout: bool = False, filters: Sequence[Filter] = ()):
        self.predictor = predictor
        self.lookout = lookout
        self.filters = list(filters) if predictor is not None else []
        self.timings = {"perception": 0.0, "control": 0.0}
        self.controller: ChenController | None = None
        self._i_speed, self._i_lanes = HIGHWAY.index("speed"), HIGHWAY.index("lanes")
        self._slots = [] if predictor is None else [(i, ESTIMATE_INDEX[n]) for i, n in
                                                    enumerate(predictor.outputs) if n in ESTIMATE_INDEX]
        self.history = History(predictor.instants if predictor is not None else (0,))   # a temporal model's frames

    @property
    def name(self) -> str:
        if self.predictor is None:
            return "oracle-extended" if self.lookout else "oracle"
        return self.predictor.name

    def estimate(self, percept: Percept) -> np.ndarray:
        """The estimate record (every label of the declaration; NaN where the model has no output), filtered."""
        if self.predictor is None:
            return np.asarray(percept.record, dtype=np.float64)[_TRUTH_OF_ESTIMATE]
        values = self.predictor(self.history.push(percept.frames))
        est = np.full(len(ESTIMATE), np.nan)
        for i, j in self._slots:
            est[j] = values[i]
        state = KEEP if self.controller is None else self.controller.state
        speed = float(percept.record[self._i_speed])
        for f in self.filters:
            f(est, speed, state)
        return est

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        est = self.estimate(percept)
        t1 = time.perf_counter()
        lanes = int(percept.record[self._i_lanes])
        controller = self.controller
        if controller is None or controller.lanes != lanes:
            controller = self.controller = make_controller(lanes, self.lookout, exact=self.predictor is None)
        action = act_on(controller, est, float(percept.record[self._i_speed]))
        self.timings["perception"] += t1 - t0
        self.timings["control"] += time.perf_counter() - t1
        return action.as_array(), est


def chen_driver(spec: DriverSpec, predictor) -> ChenDriver:
    """The driver of a checkpoint's spec: Chen's controller, or the lookout controller for a model that reads
    behind, on the predictor's estimates through the spec's filters."""
    lookout = reads_behind(predictor.outputs)
    return ChenDriver(predictor, lookout=lookout, filters=make_filters(spec, lookout))


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
        return action.as_array(), np.asarray(r, dtype=np.float64)[_TRUTH_OF_ESTIMATE]
