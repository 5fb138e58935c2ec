"""The sidewalk's drivers and its supervisor: the experts of the three behavioural modes, a deliberately poor
driver, the operation modes the world side applies (expert, autonomous, correctional under the correction rule),
and the in-process correctional driver of dataset episodes."""
from __future__ import annotations

import time
from weakref import WeakKeyDictionary

import numpy as np

from controller.sidewalk import CorrectionRule, SidewalkExpert
from controller.sidewalk import PoorDriver as Poor
from controller.sidewalk.perturbed import PerturbedExpert
from core.worlds.sidewalk import SIDEWALK
from drivestudio.loop import Percept

_NO_ESTIMATE = np.full(len(SIDEWALK.estimate_names), np.nan)


class ExpertDriver:
    """The expert of the record's behavioural mode (controller/sidewalk/experts.py), on the truth record only."""

    name = "expert"

    def __init__(self):
        self.expert = SidewalkExpert()
        self.timings = {"control": 0.0}

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        action = self.expert.action(percept.record)
        self.timings["control"] += time.perf_counter() - t0
        return action, _NO_ESTIMATE


class PoorDriver:
    """A deliberately poor driver (controller/sidewalk/poor.py), to exercise correctional operation."""

    name = "poor"

    def __init__(self, seed: int = 0):
        self.driver = Poor(seed)
        self.timings = {"control": 0.0}

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        action = np.array(self.driver.act(percept.record))
        self.timings["control"] += time.perf_counter() - t0
        return action, _NO_ESTIMATE


class PerturbedDriver:
    """The expert with the steering the car receives knocked aside now and then (controller/sidewalk/perturbed.py),
    for dataset episodes: every step is labelled with the expert's own command (world.set_label), while the car
    moves under the perturbed one (the dataset's action column)."""

    name = "perturbed expert"

    def __init__(self, world, seed: int):
        self.world, self.driver = world, PerturbedExpert(seed)
        self.timings = {"control": 0.0}

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        applied, expert = self.driver.act(percept.record)
        self.world.set_label(expert)
        self.timings["control"] += time.perf_counter() - t0
        return np.array(applied), _NO_ESTIMATE


class Supervisor:
    """What the world side applies under each operation mode: expert (the expert's command; also whenever the
    bridge's driver_mode is "manual"), autonomous (the driver's), correctional (the driver's, until the correction
    rule (controller/sidewalk/correction.py: `safety` or `strict`) hands over to the expert, and back). The world's
    record carries the operation mode of every command applied; the rule counts take-overs by clause, which the
    world's metrics report (SUPERVISORS links a world to its supervisor).

    driver_mode "human" is a person at the controls (drivestudio studio): their command is applied. Under expert
    operation the person is the expert (a demonstration); over a network it is MultiNet's RC override, recorded
    as a correction, so that percentage autonomy counts it as the expert's take-overs are counted."""

    def __init__(self, world, operation: str, rule: str = "safety"):
        self.world, self.operation = world, operation
        self.expert, self.rule = SidewalkExpert(), CorrectionRule(dt=world.dt, rule=rule)
        SUPERVISORS[world] = self

    def __call__(self, obs, action, driver_mode: str = "network"):
        if driver_mode == "human":
            name = "expert" if self.operation == "expert" else "correctional"
            self.world.set_operation(name)
            return self.world.declaration.clip_action(action), name
        expert = self.expert.action(obs.record)
        if driver_mode == "manual" or self.operation == "expert":
            name, applied = "expert", expert
        elif self.operation == "autonomous":
            name, applied = "autonomous", np.asarray(action, dtype=np.float64)
        else:
            driver = self.world.declaration.clip_action(action)
            correcting = self.rule.update(obs.record, tuple(driver), tuple(expert))
            name, applied = ("correctional", expert) if correcting else ("autonomous", driver)
        self.world.set_operation(name)
        return applied, name


SUPERVISORS: WeakKeyDictionary = WeakKeyDictionary()   # world -> its supervisor, for the metrics' report


def correction_rule(world) -> CorrectionRule | None:
    """The correction rule of the world's supervisor under correctional operation (None under any other), whose
    take-overs by clause the world's metrics report."""
    supervisor = SUPERVISORS.get(world)
    return supervisor.rule if supervisor is not None and supervisor.operation == "correctional" else None


class CorrectionalDriver:
    """In-process correctional operation for dataset episodes: the poor driver drives, the supervisor's rule lets
    the expert take over; the command returned is the one applied."""

    name = "poor+expert"

    def __init__(self, world, seed: int):
        self.poor = PoorDriver(seed)
        self.supervisor = Supervisor(world, "correctional")
        self.timings = {"control": 0.0}

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        action, _ = self.poor.act(percept)
        applied, _ = self.supervisor(percept, action)
        self.timings["control"] += time.perf_counter() - t0
        return applied, _NO_ESTIMATE
