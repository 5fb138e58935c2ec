"""The correction rules of correctional operation: when the expert takes the wheel from the autonomous driver and
when it hands back (Chowdhuri, Pankaj and Zipser, MultiNet, 2017, section 2.3: "If a human expert monitoring the car
adjusts the speed or steering on the RC transmitter, the car will automatically move into correctional mode allowing
for human correction and recovery to avoid the car flipping over or hitting an obstacle"). Here the expert is the
human, and a rule is what it watches for. Percentage autonomy, (1 - correction time / elapsed time) x 100 (the
paper's equation 3), is only as meaningful as the rule.

Two rules, built from four clauses (all read the truth record and the two commands of the step, so the rule works
in the world's process whatever transport the driver uses):

- **leaving the path**: the car's centre will be beyond the path's edge within `path_preview` seconds, or the car
  has turned away from the path (its heading more than `heading_max` from the path's: a car pointing across a path
  of 1.5-3 m, or back along it, is no longer driving it, and the expert cannot recover it by steering alone);
- **imminent collision**: its body will touch a border (hedge, bushes) within `contact_preview` seconds; or it will
  touch the next obstacle, and the way left to it is no more than the expert needs to swerve clear of it
  (controller/sidewalk/experts.py's swerve_distance, from the car's offset, heading and speed) plus
  `swerve_margin`; or it will touch the lead car (ahead or alongside, not one it has left behind) within
  `contact_preview` seconds or `contact_distance` metres (closer than `clearance` counts as touching);
- **stalled**: it has crept slower than `stall_speed` for `stall_time` seconds while the expert would drive on (its
  motor above 0.5 + `stall_motor`): a car that stops where it should go is not driving, and a person watching it
  would take over (without this clause a network that learned to stand still would score 100 % autonomy);
- **deviating from the expert**: its steering differs from the expert's by more than `steer_dev`, or its motor by
  more than `motor_dev`, for `deviation_steps` steps in a row.

`safety` (the default) takes over for the first three: what the paper's human prevents. `strict` adds the fourth,
which measures imitation of one scripted expert rather than safe driving (a network that passes an obstacle on the
other side, or drives a little slower, is taken over although nothing was at risk).

"Will" is foresight, as a person watching anticipates: the car's next seconds are rolled out from the record (its
offset, heading, speed and the command it is under) with the driver's new command held for `commit` seconds (a
driver's reaction time; after it the car keeps its heading relative to the path: a driver is expected to react, not
to hold a transient command), on a model of the car (servo rate, speed lag and acceleration limits, the grip beyond
which it runs wide: docs/sidewalk.md's car) over the path ahead taken as a circle of the record's
`curvature_ahead`. Reacting to the present state alone acts late: a car
that goes straight into a bend leaves the path on the outside half a second after its heading looks wrong, and a
car closing on a hedge at 0.9 m/s crosses the last 6 cm in 2 steps, faster than the expert can turn it away. Nor
does the person take over while the car can still be saved by the driver's own turning: for an obstacle the moment
is when waiting longer would leave the expert's swerve too little room (a car already turning round it needs
little, one heading straight at it at speed needs 2-3 m).

Hand back when the expert has driven at least `min_correction` seconds and, for the last `recovery` seconds, no
hazard was foreseen on the car's course, its heading was within `heading_ok` of the path's and its body within the
path.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from controller.sidewalk.experts import BORDER_CAP, GAP_CAP, swerve_needed
from controller.sidewalk.experts import field as value
from core.worlds.sidewalk import CAR_LENGTH, CAR_WIDTH, REAR_TO_CG, RULES, STEER_LOCK_RAD, STEP, TOP_SPEED, WHEELBASE

LEAVING, COLLISION, STALLED, DEVIATING = ("leaving the path", "imminent collision", "stalled",
                                          "deviating from the expert")
CLAUSES = {"safety": (LEAVING, COLLISION, STALLED), "strict": (LEAVING, COLLISION, STALLED, DEVIATING)}
LONGEST_OBSTACLE = 1.7     # [m] along the path (a parked bike): how long a car may be alongside one


@dataclass(frozen=True)
class CorrectionParams:
    path_preview: float = 0.6       # [s] leaving the path
    contact_preview: float = 1.0    # [s] imminent collision: a border within the next second,
    swerve_margin: float = 0.3      # [m] an obstacle when the expert's swerve needs all but this of the way to it,
    contact_distance: float = 2.0   # [m] the lead car within the next second or 2 m;
    longest: float = 3.0            # [s] the car's course foreseen at most this far,
    commit: float = 0.5             # [s] the driver's command held this long (its reaction), then the heading
    clearance: float = 0.03         # [m] closer than this counts as touching
    servo_rate: float = 8.0         # [rad/s] the rule's model of the car: servo speed,
    speed_lag: float = 0.25         # [s] time constant of the speed,
    accel: tuple = (5.0, 8.0)       # [m/s^2] speeding up, slowing down,
    grip: float = 7.0               # [m/s^2] lateral acceleration beyond which the car runs wide,
    reverse_speed: float = 3.0      # [m/s] at most backwards
    steer_dev: float = 0.3          # strict: steering difference,
    motor_dev: float = 0.25         # motor difference,
    deviation_steps: int = 8        # for 8 steps (0.27 s)
    stall_speed: float = 0.3        # [m/s]
    stall_time: float = 1.5         # [s]
    stall_motor: float = 0.03       # the expert's motor above 0.53: it would drive at more than about 0.5 m/s
    min_correction: float = 1.0     # [s]
    recovery: float = 1.0           # [s]
    heading_ok: float = 0.25        # [rad]
    heading_max: float = 1.2        # [rad] turned away from the path


def check_rule(name: str) -> str:
    if name not in RULES:
        raise ValueError(f"unknown correction rule {name!r} (rules: {', '.join(RULES)})")
    return name


def curvature_of(wheel_angle: float) -> float:
    """The curvature [1/m] the kinematic bicycle's reference point (the body's centre) turns on at a wheel angle."""
    t = math.tan(wheel_angle)
    return t / math.sqrt(WHEELBASE ** 2 + (REAR_TO_CG * t) ** 2)


def half_extent(heading: float) -> float:
    """Half the body's extent across the path [m] at a heading relative to the path."""
    return CAR_LENGTH / 2 * abs(math.sin(heading)) + CAR_WIDTH / 2 * math.cos(heading)


def foresee(record, command: tuple[float, float], p: CorrectionParams = CorrectionParams(),
            dt: float = STEP) -> str | None:
    """What will go wrong if the car drives on under `command`: "leaving the path", "imminent collision: WHAT", or
    None (the clauses of the module's docstring)."""
    hw = value(record, "path_width") / 2
    d, psi, v = value(record, "d"), value(record, "heading"), value(record, "speed")
    delta = (1.0 - 2.0 * value(record, "steer")) * STEER_LOCK_RAD
    target = (1.0 - 2.0 * min(1.0, max(0.0, command[0]))) * STEER_LOCK_RAD
    v_cmd = max((2.0 * min(1.0, max(0.0, command[1])) - 1.0) * TOP_SPEED, -p.reverse_speed)
    kp = value(record, "curvature_ahead")
    gap, od, ow = value(record, "obstacle_gap"), value(record, "obstacle_d"), value(record, "obstacle_width")
    left, right = value(record, "border_left"), value(record, "border_right")
    lead_gap, lead_d, lead_v = value(record, "lead_gap"), value(record, "lead_d"), value(record, "lead_speed")
    reach_left, reach_right = d + half_extent(psi), -d + half_extent(psi)   # the body's reach to either side now
    need = swerve_needed(record, p.clearance) + p.swerve_margin if gap < GAP_CAP else 0.0
    lead = -2 * CAR_LENGTH < lead_gap < GAP_CAP      # ahead or alongside: a lead car the car left behind is no hazard
    travelled, obstacle = 0.0, gap < GAP_CAP
    for k in range(int(round(p.longest / dt)) + 1):
        t = k * dt
        if t > max(p.path_preview, p.contact_preview) and \
                travelled > max(need if obstacle else 0.0, p.contact_distance if lead else 0.0):
            return None                                   # nothing further ahead is the expert's concern yet
        e = half_extent(psi)
        if (t <= p.path_preview and abs(d) > hw) or (t == 0.0 and abs(psi) > p.heading_max):
            return LEAVING
        soon = t <= p.contact_preview
        if soon and left < BORDER_CAP and left - (d + e - reach_left) < p.clearance:
            return f"{COLLISION}: a border"
        if soon and right < BORDER_CAP and right - (-d + e - reach_right) < p.clearance:
            return f"{COLLISION}: a border"
        if obstacle and gap - p.clearance <= travelled <= gap + LONGEST_OBSTACLE + CAR_LENGTH and \
                abs(d - od) < ow / 2 + e + p.clearance:     # the first contact foreseen: is there room to swerve?
            if travelled <= need:
                return f"{COLLISION}: an obstacle"
            obstacle = False
        if (soon or travelled <= p.contact_distance) and lead and \
                lead_gap + lead_v * t - travelled < p.clearance and abs(d - lead_d) < CAR_WIDTH / 2 + e + p.clearance:
            return f"{COLLISION}: the lead car"
        delta += max(-p.servo_rate * dt, min(p.servo_rate * dt, target - delta))
        slowing = (v_cmd - v) * v < 0 or v_cmd == 0.0
        limit = p.accel[1] if slowing else p.accel[0]
        v += max(-limit, min(limit, (v_cmd - v) / p.speed_lag)) * dt
        kappa = curvature_of(delta) if t < p.commit else kp   # after `commit` the car keeps its heading to the path
        if v * v * abs(kappa) > p.grip:                   # beyond the grip the car runs wide
            kappa = math.copysign(p.grip / (v * v), kappa)
        along = v * math.cos(psi) / max(1e-3, 1.0 - kp * d)
        d += v * math.sin(psi) * dt
        psi += (v * kappa - kp * along) * dt
        travelled += along * dt
    return None


@dataclass
class Tally:
    """Take-overs and the steps the expert drove, by the clause that caused each take-over."""

    take_overs: dict = field(default_factory=dict)
    steps: dict = field(default_factory=dict)

    def report(self, dt: float) -> dict:
        return {c: {"take_overs": self.take_overs.get(c, 0), "seconds": round(self.steps.get(c, 0) * dt, 3)}
                for c in sorted(set(self.take_overs) | set(self.steps))}


class CorrectionRule:
    def __init__(self, params: CorrectionParams = CorrectionParams(), dt: float = STEP, rule: str = "safety"):
        self.p, self.dt, self.rule = params, dt, check_rule(rule)
        self.correcting = False
        self.reason = ""             # why the expert holds the wheel, e.g. "imminent collision: an obstacle"
        self.tally = Tally()
        self._deviating = self._stalled = self._calm = self._corrected = 0

    @property
    def clause(self) -> str:
        """The clause of the present take-over ("" while the driver drives)."""
        return self.reason.split(":")[0]

    def hazard(self, record, command: tuple[float, float]) -> str | None:
        """Why the car must be taken over now for safety (leaving the path or an imminent collision), or None."""
        return foresee(record, command, self.p, self.dt)

    def update(self, record, driver: tuple[float, float], expert: tuple[float, float]) -> bool:
        """Whether the expert drives this step (and the rule's state for the next)."""
        p = self.p
        deviates = abs(driver[0] - expert[0]) > p.steer_dev or abs(driver[1] - expert[1]) > p.motor_dev
        self._deviating = self._deviating + 1 if deviates else 0
        stalled = abs(value(record, "speed")) < p.stall_speed and expert[1] > 0.5 + p.stall_motor
        self._stalled = self._stalled + 1 if stalled else 0
        if not self.correcting:
            why = self.hazard(record, driver) or \
                (STALLED if self._stalled * self.dt >= p.stall_time else None) or \
                (DEVIATING if self.rule == "strict" and self._deviating >= p.deviation_steps else None)
            if why is not None:
                self.correcting, self.reason = True, why
                self._calm = self._corrected = 0
                self.tally.take_overs[self.clause] = self.tally.take_overs.get(self.clause, 0) + 1
        else:
            self._corrected += 1
            self._calm = self._calm + 1 if self.recovered(record) else 0
            if self._corrected * self.dt >= p.min_correction and self._calm * self.dt >= p.recovery:
                self.correcting, self.reason = False, ""
                self._deviating = self._stalled = 0
        if self.correcting:
            self.tally.steps[self.clause] = self.tally.steps.get(self.clause, 0) + 1
        return self.correcting

    def recovered(self, record) -> bool:
        """The car is back on a safe course under the expert: nothing foreseen on the command it is under, its
        heading close to the path's, its body within the path."""
        hw = value(record, "path_width") / 2
        course = (value(record, "steer"), value(record, "motor"))
        return self.hazard(record, course) is None and abs(value(record, "heading")) < self.p.heading_ok and \
            abs(value(record, "d")) + CAR_WIDTH / 2 < hw
