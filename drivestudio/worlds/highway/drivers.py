"""The highway's drivers: the Chen controller on perception (the oracle: the exact indicators; or a trained
regressor's estimates, optionally smoothed), the extended oracle (the lookout controller on the exact extended
labels) and the perturbed data-collection expert."""
from __future__ import annotations

import time

import numpy as np

from controller.highway import ChenController
from controller.highway.chen import KEEP, LEFT_2, RIGHT_2
from controller.highway.expert import PerturbedExpert
from controller.highway.lookout import NOTHING_BEHIND, LookoutController
from controller.highway.pass_memory import PassMemory
from controller.highway.rear_memory import RearMemory
from core.worlds.highway import HIGHWAY, INDICATORS, REAR
from drivestudio.loop import Percept
from perception.history import History

ESTIMATE = tuple(HIGHWAY.estimate_names)
ESTIMATE_INDEX = {n: i for i, n in enumerate(ESTIMATE)}
_GAPS = [i for i, n in enumerate(ESTIMATE) if n.startswith("dist_")]
_TRUTH_OF_ESTIMATE = [HIGHWAY.index(n) for n in ESTIMATE]   # every label is a field of the truth record
_REAR = [ESTIMATE_INDEX[n] for n in REAR]
_NEIGHBOUR_GAPS = [ESTIMATE_INDEX["dist_LL"], ESTIMATE_INDEX["dist_RR"]]   # what the controller's rule 1 reads
_REAR_SIDES = [(ESTIMATE_INDEX[f"dist_{k}B"], ESTIMATE_INDEX[f"closing_{k}B"]) for k in "LR"]   # what L1 reads

# the drivers on exact labels, by --model name: whether each looks beside and behind (controller/highway/lookout.py)
ORACLES = {"oracle": False, "oracle-extended": True}


def reads_behind(outputs) -> bool:
    """Whether a model estimates the cars beside and behind (the four rear labels of the extended set): such a
    model drives with the lookout controller, as the extended oracle does on the exact labels; any other with
    Chen's, which sees only ahead."""
    return set(REAR) <= set(outputs)


def make_controller(lanes: int, lookout: bool) -> ChenController:
    """The controller of a driver: the Chen controller, or the lookout controller (rules L1-L3 on top)."""
    return LookoutController(lanes) if lookout else ChenController(lanes)


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
    every network is compared with) and the Chen controller. The controller is made on the first frame, when the
    lane count is known."""

    def __init__(self, predictor=None, smoothing: float = 0.0, gap_hold: float = 0.0, lookout: bool = False,
                 pass_memory: float = 0.0, rear_memory: float = 0.0):
        self.predictor = predictor
        self.lookout = lookout
        self.smoothing, self.gap_hold = smoothing, gap_hold
        # a car being passed in a neighbour lane, carried on unseen (controller/highway/pass_memory.py)
        self.pass_memory = [PassMemory(max_s=pass_memory) for _ in _NEIGHBOUR_GAPS] \
            if pass_memory > 0 and predictor is not None else []
        # a car seen closing in the mirror, held alongside once lost (controller/highway/rear_memory.py)
        self.rear_memory = [RearMemory(max_s=rear_memory) for _ in _REAR_SIDES] \
            if rear_memory > 0 and predictor is not None and lookout else []
        self.timings = {"perception": 0.0, "control": 0.0}
        self.controller: ChenController | None = None
        self._i_speed, self._i_lanes = HIGHWAY.index("speed"), HIGHWAY.index("lanes")
        self._slots = [] if predictor is None else [(i, ESTIMATE_INDEX[n]) for i, n in
                                                    enumerate(predictor.outputs) if n in ESTIMATE_INDEX]
        self._smoothed: np.ndarray | None = None
        self._held: np.ndarray | None = None
        self.history = History(predictor.instants if predictor is not None else (0,))   # a temporal model's frames

    @property
    def name(self) -> str:
        if self.predictor is None:
            return "oracle-extended" if self.lookout else "oracle"
        return self.predictor.name

    def estimate(self, percept: Percept) -> np.ndarray:
        """The estimate record (every label of the declaration; NaN where the model has no output)."""
        if self.predictor is None:
            return np.asarray(percept.record, dtype=np.float64)[_TRUTH_OF_ESTIMATE]
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
        self._remember(est, float(percept.record[self._i_speed]))
        return est

    def _remember(self, est: np.ndarray, speed: float) -> None:
        """The memories of cars out of view, in place: the pass memory on the neighbour gaps ahead, the rear memory
        on the gaps and closing speeds behind. A lane change forgets them (the lanes change meaning): the pass
        memory for its whole length, the rear memory once the host is on the marking (until then L2 reads it)."""
        state = KEEP if self.controller is None else self.controller.state
        for k, (memory, i) in enumerate(zip(self.pass_memory, _NEIGHBOUR_GAPS)):
            if state != KEEP:
                memory.reset()
            # with the rear memory, the mirror takes a passed car over (controller/highway/pass_memory.py)
            behind = bool(est[_REAR_SIDES[k][0]] < self.rear_memory[k].near) if self.rear_memory else None
            est[i] = memory.filter(float(est[i]), speed, behind)
        for rear, (g, c) in zip(self.rear_memory, _REAR_SIDES):
            if state in (LEFT_2, RIGHT_2):
                rear.reset()
            est[g], est[c] = rear.filter(float(est[g]), float(est[c]))

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        est = self.estimate(percept)
        t1 = time.perf_counter()
        lanes = int(percept.record[self._i_lanes])
        controller = self.controller
        if controller is None or controller.lanes != lanes:
            controller = self.controller = make_controller(lanes, self.lookout)
        action = act_on(controller, est, float(percept.record[self._i_speed]))
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
        return action.as_array(), np.asarray(r, dtype=np.float64)[_TRUTH_OF_ESTIMATE]
