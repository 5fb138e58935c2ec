"""The sidewalk world's experts, one per behavioural mode (Chowdhuri, Pankaj and Zipser, MultiNet, 2017):

- direct: follow the path at a steady pace and steer round obstacles;
- follow: keep an even distance behind the lead car, modulating speed with it;
- furtive: creep slowly close beside the bordering hedges and bushes; where there is no border, speed up along
  the path until one is found.

They read the truth record only (SIDEWALK's fields: what a driver process over the bridge receives), so the same
expert drives in the world's process, over the bridge and as the correction rule's reference.

Each mode chooses a lateral target (an offset d from the centreline) and a speed; one steering law and one motor
law turn them into commands. Steering is pure pursuit of a point `lookahead` metres along the path at the
target offset, the path ahead taken as a circle of the record's curvature_ahead; the wheel angle that gives the
pursued curvature is exact for the car's kinematic bicycle. The motor command is the target speed (the car's
speed control follows it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from core.worlds.sidewalk import (
    CAR_LENGTH,
    CAR_WIDTH,
    MODES,
    REAR_TO_CG,
    SIDEWALK,
    STEER_LOCK_RAD,
    TOP_SPEED,
    WHEELBASE,
)

BORDER_CAP = 5.0     # [m] the record's border distance where there is no border
GAP_CAP = 30.0       # [m] the record's obstacle_gap / lead_gap when there is nothing
SWERVE_ACCEL = 2.5   # [m/s^2] sideways: a swerve round an obstacle at speed turns on a radius of speed^2 / this,
SWERVE_RADIUS = 1.0  # [m] at least this,
SWERVE_ANGLE = 1.0   # [rad] to a heading of at most this from the path's
REACTION = 0.15      # [s] before a swerve bites: the servo (0.1 s lock to lock) and the step


@dataclass(frozen=True)
class ExpertParams:
    cruise: float = 3.0            # [m/s] direct
    lateral_accel: float = 2.2     # [m/s^2] at most in bends
    near_obstacle: float = 2.0     # [m/s] at most with an obstacle within 3 m (direct, follow)
    edge_margin: float = 0.12      # [m] kept between the body and the path's edge
    pass_margin: float = 0.18      # [m] kept between the body and an obstacle it passes
    ramp: tuple = (1.0, 4.0)       # [m] obstacle_gap over which the car swings out (fully out below the first)
    swerve_margin: float = 0.3     # [m] swings out fully at once when the swerve needs all but this of the gap,
    urgent_look: float = 0.5       # [m] pursuing a point this close,
    urgent_speed: float = 1.0      # [m/s] at most this fast
    follow_gap: float = 1.2        # [m] lead_gap follow mode keeps
    follow_gain: float = 1.2       # [1/s] speed per metre of gap error
    follow_max: float = 4.5        # [m/s]
    furtive_slow: float = 0.9      # [m/s] beside a border
    furtive_fast: float = 3.6      # [m/s] looking for one
    hug_margin: float = 0.06       # [m] between the body and the path's edge on the bordered side (furtive)
    lookahead: tuple = (0.6, 0.35, 1.6)   # [m] pure pursuit distance: base + gain * speed, at most the last


_I = {n: i for i, n in enumerate(SIDEWALK.truth_names)}


def field(record, name: str) -> float:
    return float(record[_I[name]])


def wheel_angle_for(kappa: float) -> float:
    """Front-wheel angle [rad, positive left] for which the kinematic bicycle's reference point (its body's
    centre) turns on curvature kappa [1/m]: tan(delta) = kappa * L / sqrt(1 - (kappa * l_r)^2)."""
    k = max(-1.0 / REAR_TO_CG + 1e-6, min(1.0 / REAR_TO_CG - 1e-6, kappa))
    return math.atan(k * WHEELBASE / math.sqrt(1.0 - (k * REAR_TO_CG) ** 2))


def steer_command(wheel_angle: float) -> float:
    """The steering command [0, 1] for a wheel angle (positive left): 0.5 straight, 1 full right."""
    return min(1.0, max(0.0, 0.5 - wheel_angle / (2.0 * STEER_LOCK_RAD)))


def motor_command(speed: float) -> float:
    """The motor command [0, 1] for a forward speed [m/s]: 0.5 stop, 1 top speed."""
    return min(1.0, max(0.0, 0.5 + speed / (2.0 * TOP_SPEED)))


def pursue(record, target_d: float, lookahead: float) -> float:
    """Pure pursuit: the curvature [1/m] that brings the car to the point `lookahead` metres along the path at
    offset target_d, the path ahead taken as a circle of curvature curvature_ahead."""
    d, psi = field(record, "d"), field(record, "heading")
    k = field(record, "curvature_ahead")
    a = k * lookahead
    if abs(k) > 1e-9:
        px, py = math.sin(a) / k, (1.0 - math.cos(a)) / k
    else:
        px, py = lookahead, 0.0
    px, py = px - target_d * math.sin(a), py + target_d * math.cos(a)
    dx, dy = px, py - d
    c, s = math.cos(psi), math.sin(psi)
    x, y = c * dx + s * dy, -s * dx + c * dy
    return 2.0 * y / max(x * x + y * y, 1e-6)


def swerve_distance(speed: float, lateral: float, heading: float = 0.0) -> float:
    """The distance along the path [m] a swerve needs to move the car `lateral` metres sideways (towards the side it
    swerves to), from a heading `heading` [rad] relative to the path (positive: already turned towards that side):
    the reaction, then an arc of radius max(SWERVE_RADIUS, speed^2 / SWERVE_ACCEL) up to SWERVE_ANGLE, then straight
    on at that angle. Both the expert (when to swerve at once) and the correction rule (when the expert must take
    over) judge an obstacle ahead by it.

    A car already clear (`lateral` <= 0) needs no swerve, unless it is heading back towards the obstacle and would
    use up its room to spare (-lateral) while it turns parallel: then it needs the way covered while it does (the
    reaction, then the arc to the path's heading). A car passing an obstacle with a millimetre to spare at 2.9 m/s,
    0.08 rad towards it, needs 0.7 m of way; one passing with half a metre to spare needs none."""
    r = max(SWERVE_RADIUS, speed * speed / SWERVE_ACCEL)
    if lateral <= 0.0:
        closing = max(0.0, min(math.pi / 2, -heading))
        closes = abs(speed) * REACTION * math.sin(closing) + r * (1.0 - math.cos(closing))
        return abs(speed) * REACTION + r * math.sin(closing) if closes > -lateral else 0.0
    psi0 = max(-math.pi / 2, min(SWERVE_ANGLE, heading))
    arc = r * (math.cos(psi0) - math.cos(SWERVE_ANGLE))       # sideways while turning to the steepest heading
    if arc >= lateral:
        psi = math.acos(math.cos(psi0) - lateral / r)
        along = r * (math.sin(psi) - math.sin(psi0))
    else:
        along = r * (math.sin(SWERVE_ANGLE) - math.sin(psi0)) + (lateral - arc) / math.tan(SWERVE_ANGLE)
    return abs(speed) * REACTION + along


def swerve_needed(record, margin: float) -> float:
    """The shortest swerve [m along the path] that takes the car's body `margin` clear of the next obstacle, to its
    left or to its right where the path leaves room (0: it is clear already; inf: no side has room)."""
    d, psi, v = field(record, "d"), field(record, "heading"), field(record, "speed")
    od, ow = field(record, "obstacle_d"), field(record, "obstacle_width")
    lim = field(record, "path_width") / 2 - CAR_WIDTH / 2
    tight = ow / 2 + CAR_WIDTH / 2 + margin
    out = [swerve_distance(v, (x - d) * side, psi * side)
           for x, side in ((od + tight, 1.0), (od - tight, -1.0)) if abs(x) <= lim]
    return min(out, default=math.inf)


def _smooth(u: float) -> float:
    u = min(1.0, max(0.0, u))
    return 0.5 - 0.5 * math.cos(math.pi * u)


class SidewalkExpert:
    """The three experts behind one act(record) -> (steer, motor, why); the mode is the record's behaviour."""

    def __init__(self, params: ExpertParams = ExpertParams()):
        self.p = params

    # --- lateral targets ---------------------------------------------------------------------------------------
    def limits(self, record) -> tuple[float, float]:
        """The range of centre offsets [m] that keep the body edge_margin inside the path."""
        hw = field(record, "path_width") / 2 - CAR_WIDTH / 2 - self.p.edge_margin
        return -hw, hw

    def furtive_side(self, record) -> float:
        """+1 to hug a border on the left, -1 on the right, 0 where there is none. With borders on both sides the
        nearer one wins, judged half a second ahead at the present heading (so that a car crossing the path
        does not change its mind halfway)."""
        left, right = field(record, "border_left"), field(record, "border_right")
        if min(left, right) >= BORDER_CAP - 1e-6:
            return 0.0
        ahead = field(record, "speed") * math.sin(field(record, "heading")) * 0.5   # lateral move, + left
        return 1.0 if left - ahead <= right + ahead else -1.0

    def nominal(self, record, mode: str) -> float:
        """The offset [m] a mode keeps when no obstacle is in the way."""
        if mode == "furtive":
            side = self.furtive_side(record)
            hw = field(record, "path_width") / 2 - CAR_WIDTH / 2 - self.p.hug_margin
            return side * hw
        return 0.0

    def around_obstacle(self, record, want: float) -> float:
        """The offset to drive at: `want`, or, when the next obstacle lies in the way of the car going from where
        it is to `want`, an offset beside it, blended in over the last metres before it (fully from ramp[0] on).

        Beside it means on the left or on the right of it, at least `tight` from its centre (the body clears it)
        and `pass_margin` more where the path leaves room; of the two sides the one that costs the least swerving,
        2 |side - d| + |side - want|, wins (moving from where the car is counts double). So a car already beside an
        obstacle's edge stays there, and one that would have to cut across in front of it passes on its side. Closer
        than ramp[1] it never cuts across, not even where its own side is narrower than the expert would choose (a
        car a driver left squeezed between the obstacle and the path's edge squeezes by, as far from the obstacle as
        the edge allows), and where the swerve needs all the room left (a car the expert takes
        over near an obstacle, from wherever the driver left it) it swerves fully at once rather than blending
        in."""
        gap = field(record, "obstacle_gap")
        if gap >= GAP_CAP - 1e-6:
            return want
        d = field(record, "d")
        od, ow = field(record, "obstacle_d"), field(record, "obstacle_width")
        tight = ow / 2 + CAR_WIDTH / 2 + 0.08
        comfort = ow / 2 + CAR_WIDTH / 2 + self.p.pass_margin
        if min(d, want) >= od + tight or max(d, want) <= od - tight:
            return want                               # it passes beside it as it is
        lim = field(record, "path_width") / 2 - CAR_WIDTH / 2 - min(self.p.edge_margin, self.p.hug_margin)
        sides = []
        if od + tight <= lim:
            sides.append(min(lim, max(min(lim, od + comfort), want)))
        if od - tight >= -lim:
            sides.append(max(-lim, min(max(-lim, od - comfort), want)))
        if not sides:                                  # no room at all (a path file may do that): the roomier side
            sides = [lim if lim - od >= od + lim else -lim]
        side = min(sides, key=lambda p: 2 * abs(p - d) + abs(p - want))
        late = self.urgent(record)
        if gap < self.p.ramp[1]:                       # too close to cut across in front of it: the car's own side
            own = [p for p in sides if (p - od) * (d - od) > 0]
            if own:
                side = min(own, key=lambda p: abs(p - d))
            elif abs(d - od) >= ow / 2 + CAR_WIDTH / 2:  # beside it where the expert would not have passed: it
                edge = field(record, "path_width") / 2 - CAR_WIDTH / 2   # squeezes by, as far from it as the
                side = min(edge, max(-edge, od + math.copysign(tight, d - od)))   # path's edge allows
        ramp = _smooth((self.p.ramp[1] - gap) / (self.p.ramp[1] - self.p.ramp[0]))
        w = 1.0 if gap <= self.p.ramp[0] or late else ramp
        return (1.0 - w) * want + w * side

    def beside_lead(self, record, target: float) -> float:
        """`target`, or, with the lead car alongside (a driver drew level with it or passed it: lead_gap between
        minus two car lengths and 0), the nearest offset on the car's own side of it that keeps the bodies
        pass_margin apart: the expert stops and lets it go on rather than steer back into it."""
        gap = field(record, "lead_gap")
        if not -2 * CAR_LENGTH - self.p.pass_margin < gap < 0.0:
            return target
        d, ld = field(record, "d"), field(record, "lead_d")
        apart = CAR_WIDTH + self.p.pass_margin
        return max(target, ld + apart) if d >= ld else min(target, ld - apart)

    def urgent(self, record) -> bool:
        """The next obstacle is in the way and the swerve round it needs all the room left but swerve_margin: swerve
        fully at once, sharply (a short pursuit distance) and slowly (a car the expert takes over late, from
        wherever a driver left it)."""
        gap = field(record, "obstacle_gap")
        if gap >= GAP_CAP - 1e-6:
            return False
        needed = swerve_needed(record, 0.08)
        return 0.0 < needed and gap <= needed + self.p.swerve_margin

    # --- speeds ------------------------------------------------------------------------------------------------
    def bend_speed(self, record) -> float:
        k = max(abs(field(record, "curvature")), abs(field(record, "curvature_ahead")))
        return math.sqrt(self.p.lateral_accel / k) if k > 1e-9 else math.inf

    def speed(self, record, mode: str) -> tuple[float, str]:
        p = self.p
        bend = self.bend_speed(record)
        near = field(record, "obstacle_gap") < 3.0
        if mode == "follow" and field(record, "lead_gap") < GAP_CAP - 1e-6:
            gap = field(record, "lead_gap")
            v = field(record, "lead_speed") + p.follow_gain * (gap - p.follow_gap)
            v = 0.0 if gap < 0.4 else min(p.follow_max, max(0.0, v))
            return min(v, bend), "following"
        if mode == "furtive":
            if self.furtive_side(record) != 0.0:
                return min(p.furtive_slow, bend), "creeping beside a border"
            return min(p.furtive_fast, bend, p.near_obstacle if near else math.inf), "looking for a border"
        return min(p.cruise, bend, p.near_obstacle if near else math.inf), "cruising"

    # --- commands ----------------------------------------------------------------------------------------------
    def act(self, record, mode: str | None = None) -> tuple[float, float, str]:
        """(steer, motor, what it is doing) for a truth record; the mode defaults to the record's behaviour."""
        mode = mode or MODES[int(field(record, "behaviour"))]
        # clamped to the path's edge only: around_obstacle keeps the expert's margins where the path has room for them
        edge = field(record, "path_width") / 2 - CAR_WIDTH / 2
        target = self.beside_lead(record, self.around_obstacle(record, self.nominal(record, mode)))
        target = min(edge, max(-edge, target))
        v, why = self.speed(record, mode)
        base, gain, most = self.p.lookahead
        look = min(most, base + gain * abs(field(record, "speed")))
        if self.urgent(record):
            look = min(look, self.p.urgent_look)
            v, why = min(v, self.p.urgent_speed), "swerving round an obstacle"
        steer = steer_command(wheel_angle_for(pursue(record, target, look)))
        return steer, motor_command(v), why

    def action(self, record, mode: str | None = None) -> np.ndarray:
        steer, motor, _ = self.act(record, mode)
        return np.array([steer, motor])
