"""The correction rule of correctional operation (Chowdhuri, Pankaj and Zipser, MultiNet, 2017: a human watching
the autonomous car takes over to avoid a crash and hands back after the recovery; those frames are recorded and
flagged). Here the expert is the human, and this rule is when it takes over and hands back.

Take over at a step when any of these holds (all from the truth record, and the driver's and the expert's
commands for that step):

1. leaving the path: the body reaches over the path's edge (|d| + width / 2 > half the path's width), or will
   within `preview` seconds at its present speed and heading;
2. nearing a collision: the next obstacle lies in the car's lane (their lateral extents overlap, with
   `lane_margin`) less than `time_to_contact` seconds ahead at the present speed (and at least `min_gap`
   metres); or the body is closer than `border_min` to a border; or closer than `lead_min` to the lead car;
3. deviating from the expert: the driver's steering differs from the expert's by more than `steer_dev`, or its
   motor by more than `motor_dev`, for `deviation_steps` steps in a row;
4. stalling: the car has crept slower than `stall_speed` for `stall_time` seconds while the expert would drive on
   (its motor above 0.5 + `stall_motor`): a car that stops where it should go is not driving, and a person watching
   it would take over (without this rule a network that learned to stand still would score 100 % autonomy).

Hand back when the expert has driven at least `min_correction` seconds and, for the last `recovery` seconds,
none of 1 and 2 held, the car's heading was within `heading_ok` of the path's and its body at least
`inside_margin` inside the path.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from controller.sidewalk.experts import GAP_CAP, field
from core.worlds.sidewalk import CAR_WIDTH, STEP


@dataclass(frozen=True)
class CorrectionParams:
    preview: float = 0.5            # [s]
    time_to_contact: float = 0.8    # [s]
    min_gap: float = 0.3            # [m]
    lane_margin: float = 0.05       # [m]
    border_min: float = 0.06        # [m]
    lead_min: float = 0.4           # [m]
    steer_dev: float = 0.3
    motor_dev: float = 0.25
    deviation_steps: int = 8        # 0.27 s
    stall_speed: float = 0.3        # [m/s]
    stall_time: float = 1.5         # [s]
    stall_motor: float = 0.03       # the expert's motor above 0.53: it would drive at more than about 0.5 m/s
    min_correction: float = 1.0     # [s]
    recovery: float = 1.0           # [s]
    heading_ok: float = 0.25        # [rad]
    inside_margin: float = 0.15     # [m]


class CorrectionRule:
    def __init__(self, params: CorrectionParams = CorrectionParams(), dt: float = STEP):
        self.p, self.dt = params, dt
        self.correcting = False
        self.reason = ""
        self._deviating = 0
        self._stalled = 0
        self._calm = 0
        self._corrected = 0

    def hazard(self, record) -> str | None:
        """Why the car must be taken over now (rules 1 and 2), or None."""
        p = self.p
        hw = field(record, "path_width") / 2
        d, psi, v = field(record, "d"), field(record, "heading"), field(record, "speed")
        if abs(d) + CAR_WIDTH / 2 > hw:
            return "leaving the path"
        if abs(d + v * math.sin(psi) * p.preview) + CAR_WIDTH / 2 > hw:
            return "about to leave the path"
        gap = field(record, "obstacle_gap")
        if gap < GAP_CAP:
            in_lane = abs(d - field(record, "obstacle_d")) < field(record, "obstacle_width") / 2 + CAR_WIDTH / 2 + \
                p.lane_margin
            if in_lane and gap < max(p.min_gap, v * p.time_to_contact):
                return "nearing an obstacle"
        if min(field(record, "border_left"), field(record, "border_right")) < p.border_min:
            return "nearing a border"
        if field(record, "lead_gap") < p.lead_min:
            return "nearing the lead car"
        return None

    def update(self, record, driver: tuple[float, float], expert: tuple[float, float]) -> bool:
        """Whether the expert drives this step (and the rule's state for the next)."""
        p = self.p
        hazard = self.hazard(record)
        deviates = abs(driver[0] - expert[0]) > p.steer_dev or abs(driver[1] - expert[1]) > p.motor_dev
        self._deviating = self._deviating + 1 if deviates else 0
        stalled = abs(field(record, "speed")) < p.stall_speed and expert[1] > 0.5 + p.stall_motor
        self._stalled = self._stalled + 1 if stalled else 0
        if not self.correcting:
            why = hazard or ("deviating from the expert" if self._deviating >= p.deviation_steps else None) or \
                ("stalled" if self._stalled * self.dt >= p.stall_time else None)
            if why is not None:
                self.correcting, self.reason = True, why
                self._calm, self._corrected = 0, 0
            return self.correcting
        self._corrected += 1
        hw = field(record, "path_width") / 2
        settled = hazard is None and abs(field(record, "heading")) < p.heading_ok and \
            abs(field(record, "d")) + CAR_WIDTH / 2 < hw - p.inside_margin
        self._calm = self._calm + 1 if settled else 0
        if self._corrected * self.dt >= p.min_correction and self._calm * self.dt >= p.recovery:
            self.correcting, self.reason = False, ""
            self._deviating = self._stalled = 0
        return self.correcting
