"""Closed-loop driving for the controller tests: the Chen controller (or the lookout controller, which also reads
the exact rear labels) on the exact indicators at 10 Hz."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from controller.highway import ChenController
from controller.highway.lookout import LookoutController
from sim.highway.traffic import ScriptedTraffic
from sim.highway.truth import affordances, rear_indicators
from sim.highway.vehicle import VehicleParams, VehicleState, step_vehicle
from sim.track import Track

DT = 0.1  # [s] the controller's 10 Hz frame


@dataclass
class Trace:
    """Per frame, before the command of that frame is applied."""

    s: list = field(default_factory=list)          # [m]
    d: list = field(default_factory=list)          # [m]
    heading: list = field(default_factory=list)    # [rad]
    speed: list = field(default_factory=list)      # [m/s]
    lane: list = field(default_factory=list)       # lanes_left of the host car
    states: list = field(default_factory=list)     # controller state after the frame
    gaps: list = field(default_factory=list)       # signed along-track gap to each other car [m]
    lateral: list = field(default_factory=list)    # lateral offset of each other car from the host [m]
    final: VehicleState | None = None

    def arrays(self):
        return {k: np.asarray(v) for k, v in self.__dict__.items() if k != "final"}


def drive(track: Track, ctrl: ChenController, start: VehicleState, seconds: float,
          traffic: ScriptedTraffic | None = None, stop=None) -> Trace:
    """Drive `seconds` of simulated time; `stop(trace)` may end the run early."""
    state, trace = start, Trace()
    for _ in range(int(round(seconds / DT))):
        cars_s = traffic.s if traffic is not None else np.zeros(0)
        cars_d = traffic.d if traffic is not None else np.zeros(0)
        ind = affordances(track, state.s, state.d, state.heading, cars_s, cars_d)
        if isinstance(ctrl, LookoutController):
            length = traffic.length if traffic is not None else np.zeros(0)
            speed = traffic.speed if traffic is not None else np.zeros(0)
            rear = rear_indicators(track, state.s, state.d, VehicleParams().length, state.speed, cars_s, cars_d,
                                   length, speed)
            action = ctrl.act(ind, state.speed, rear)
        else:
            action = ctrl.act(ind, state.speed)
        trace.s.append(state.s)
        trace.d.append(state.d)
        trace.heading.append(state.heading)
        trace.speed.append(state.speed)
        trace.lane.append(track.lane_of(state.d))
        trace.states.append(ctrl.state)
        trace.gaps.append(track.gap(state.s, cars_s))
        trace.lateral.append(np.asarray(cars_d) - state.d)
        state = step_vehicle(state, action, DT, track)
        if traffic is not None:
            traffic.step(DT)
        if stop is not None and stop(trace):
            break
    trace.final = state
    return trace


def collided(trace: Trace, along: float = 5.0, across: float = 2.0) -> bool:
    """True when some other car's centre came within `along` [m] along and `across` [m] across the track."""
    gaps, lateral = np.asarray(trace.gaps), np.asarray(trace.lateral)
    return bool(np.any((np.abs(gaps) < along) & (np.abs(lateral) < across)))
