"""A lane change that looks before it moves: the Chen controller plus the cars beside and behind the host car.

DeepDriving's indicators see only cars ahead, so the Chen controller changes lanes into a car alongside or
arriving from behind, and pulls out from a short following gap while still accelerating. This controller reads
the extended labels too (core/worlds/highway.py REAR: the bumper gap to the nearest car alongside or behind in
the lanes left and right, and its closing speed) and adds five rules to docs/controller.md's seven
(docs/controller.md, "The lookout"; docs/explanation/lookout.md argues every number):

    L1  look: a change (rule 2 or 3) starts only when the target lane's rear gap is at least the safe gap
        need(c, T) = min_gap + c+ T + c+^2 / (2 follower_decel), c+ = max(c, 0), with T = crossing(v) + margin_time:
        c is the closing speed the car behind will have (its own, plus what L3 will take off the host's speed), v
        the host's speed under L3, and crossing(v) = max(min_crossing_time, crossing_distance / v) the time the
        host's centre takes to reach the marking;
    L2  abort: until the host car's centre crosses the marking, a change is given up, and the car steers back into
        its lane, when the target lane's rear gap falls below need(c, crossing(v)), or a car ahead in it comes
        closer than ahead_min;
    L3  pull out behind the leader: until the host car is laterally clear of the lane it leaves (its centre
        clear_margin past the marking), its speed stays within the follow curve (rule 2) of the car ahead in
        that lane;
    L4  cross at lane keeping's gain: phase 2 of a change (and of an abort's way back) steers with coe_phase_2
        (rule 4's 1.5) instead of 20, with which a change to the inside of a bend of 100 m radius or less stalls
        on the marking;
    L5  stop in time (with stop_in_time: the extended oracle's, on exact labels): while the in-lane system sees a
        car ahead, the host's speed stays at most the speed from which it stops behind that car, braking at
        stop_decel after stop_delay, with stop_margin to spare, should the car brake to a standstill at lead_decel:
        v <= b (-tau + sqrt(tau^2 + 2 R / b)), R = dist_MM - car_length - stop_margin + v_lead^2 / (2 lead_decel),
        v_lead = speed - closing, the closing speed from dist_MM's change over a frame (a jump of more than
        gap_jump is another car: closing 0 then); above it the host brakes with stop_gain. The closing speed is a
        difference of two gaps, exact on exact labels and as noisy as a network's gap estimates otherwise, so a
        network's driver goes without L5 until a filtered closing speed is measured with it.

Everything else is the Chen controller, unchanged. Depends only on numpy and the highway's declaration.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controller.highway.chen import KEEP, LEFT_1, LEFT_2, RIGHT_1, RIGHT_2, ChenController, ChenParams
from core.worlds.highway import CLOSING_INACTIVE, GAP_MAX, REAR, REAR_RANGE, Action

LEFT_CHANGE, RIGHT_CHANGE = (LEFT_1, LEFT_2), (RIGHT_1, RIGHT_2)
NOTHING_BEHIND = (REAR_RANGE, REAR_RANGE, CLOSING_INACTIVE, CLOSING_INACTIVE)   # the rear labels of an empty road


@dataclass(frozen=True)
class LookoutParams:
    """The lookout's constants (docs/controller.md, "The lookout"; docs/explanation/lookout.md argues each)."""

    min_gap: float = 5.0             # [m] bumper gap to a car alongside or behind that is never cut in front of
    crossing_distance: float = 14.0  # [m] road the host covers from the decision until its centre crosses the marking
    min_crossing_time: float = 0.7   # [s] ... but never faster than this (the steering rate limit, above 20 m/s)
    margin_time: float = 0.7         # [s] L1's closing time beyond the crossing
    follower_decel: float = 4.0      # [m/s^2] the follower's braking: the calmest SUMO driver's comfortable decel
    ahead_min: float = 10.0        # [m] centre to centre: a car this close ahead in the target lane aborts (L2)
    clear_margin: float = 0.3        # [m] past the marking the host's body is clear of the leader it pulls out from
    coe_phase_2: float = 1.5         # [-] L4: the steering divisor of phase 2 (rule 4's coe_keep, not rule 5's 20)
    stop_in_time: bool = False       # L5 on (the extended oracle)
    frame: float = 0.1               # [s] L5: between two calls (the controller's 10 Hz)
    stop_decel: float = 6.0          # [m/s^2] L5: the braking the host plans with (its brakes give 11)
    stop_delay: float = 0.3          # [s] L5: before that braking is reached (rule 7's speed control builds it)
    lead_decel: float = 8.0          # [m/s^2] L5: the hardest the car ahead is expected to brake
    car_length: float = 4.8          # [m] L5: centre-to-centre gap less the bumper gap (half of two car lengths)
    stop_margin: float = 2.0         # [m] L5: the bumper gap left at a standstill
    gap_jump: float = 3.0            # [m] L5: dist_MM changing more than this in a frame is another car
    stop_gain: float = 0.5           # [1/(m/s)] L5: brake = stop_gain (speed - limit) above the limit, five times
                                     # rule 7's brake_gain, so that 1 m/s too fast brakes at about stop_decel


MIN_SPEED = 0.5   # [m/s] crossing() of a (nearly) standing host: as at this speed (28 s at 14 m)


def crossing(speed: float, p: LookoutParams = LookoutParams()) -> float:
    """crossing(v) [s]: from the decision until the host's centre crosses the marking, at `speed` [m/s]."""
    return max(p.min_crossing_time, p.crossing_distance / max(float(speed), MIN_SPEED))


def safe_gap(closing: float, speed: float, p: LookoutParams = LookoutParams(), abort: bool = False) -> float:
    """need(c, T) [m]: the rear gap a change needs to a car closing in at `closing` [m/s] when the host drives at
    `speed` [m/s]: T = crossing(v) + margin_time to start one (L1), crossing(v) alone to go on with it (L2)."""
    c = max(0.0, float(closing))
    time = crossing(speed, p) + (0.0 if abort else p.margin_time)
    return p.min_gap + c * time + c * c / (2.0 * p.follower_decel)


class LookoutController(ChenController):
    """The Chen controller with rules L1-L5. `act(indicators, speed, rear)`: rear holds dist_LB, dist_RB,
    closing_LB, closing_RB (REAR order); without it nothing is beside or behind and this is the Chen controller."""

    def __init__(self, lanes: int, params: ChenParams | None = None, lookout: LookoutParams = LookoutParams()):
        self.lookout = lookout
        super().__init__(lanes, params or ChenParams())   # calls reset()

    def reset(self) -> None:
        super().reset()
        self._rear: dict[str, float] = dict(zip(REAR, NOTHING_BEHIND))
        self._aborts = self._refusals = 0
        self._refused = ""
        self._speed = 0.0
        self._last_mm: float | None = None   # L5: dist_MM of the last frame, while a car was ahead
        self._stop_limit = self.params.no_slow_down   # L5's limit on this frame

    @property
    def aborts(self) -> int:
        """Lane changes given up so far (L2)."""
        return self._aborts

    @property
    def refusals(self) -> int:
        """Frames on which rule 2 or 3 wanted a change that L1 refused."""
        return self._refusals

    @property
    def stop_limit(self) -> float:
        """L5's limit [m/s] on the last frame (inf: none)."""
        return self._stop_limit

    @property
    def refused(self) -> str:
        """The side L1 refused on the last frame ("left", "right", or "")."""
        return self._refused

    def act(self, indicators, speed: float, rear=None) -> Action:
        values = np.asarray(NOTHING_BEHIND if rear is None else rear, dtype=np.float64).reshape(-1)
        if values.size != len(REAR):
            raise ValueError(f"expected the {len(REAR)} rear labels ({', '.join(REAR)}), got {values.size}")
        self._rear = dict(zip(REAR, values.tolist()))
        self._speed = float(speed)
        self._refused = ""
        self._stop_limit = self.params.no_slow_down
        action = super().act(indicators, speed)
        over = self._speed - self._stop_limit
        if over > 0:   # L5 brakes harder than rule 7's speed control would
            brake = max(action.brake, min(1.0, self.lookout.stop_gain * over))
            return Action(action.steer, 0.0, brake)
        return action

    # --- L1: look before moving --------------------------------------------------------------------------------
    def rear_safe(self, side: str, v: dict[str, float], abort: bool = False) -> bool:
        """The rear gap in the lane on `side` is at least need(c, T), for the host's speed once L3 holds it to the
        follow speed of the car ahead in the lane it leaves, and the closing speed of the car there then."""
        k = "L" if side == "left" else "R"
        if self._rear[f"dist_{k}B"] >= REAR_RANGE:
            return True   # nothing known within the labels' range can reach the host (docs/explanation/lookout.md)
        speed = min(self._speed, self._change_speed_limit(v, side))
        closing = self._rear[f"closing_{k}B"] + (self._speed - speed)
        return self._rear[f"dist_{k}B"] >= safe_gap(closing, speed, self.lookout, abort)

    def _target_safe(self, side: str, v: dict[str, float]) -> bool:
        if self.rear_safe(side, v):
            return True
        self._refusals += 1
        self._refused = side
        return False

    # --- L2: abort until the centre crosses ---------------------------------------------------------------------
    def _target(self, v: dict[str, float]) -> float:
        if self._state in LEFT_CHANGE + RIGHT_CHANGE and not self._crossed(v) and not self._still_safe(v):
            self._abort(v)
        center_line = super()._target(v)
        if self._state in (LEFT_2, RIGHT_2):
            self._coe_steer = self.lookout.coe_phase_2   # L4
        return center_line

    def _crossed(self, v: dict[str, float]) -> bool:
        """The host car's centre is past the marking it is crossing (the on-marking toMarking_M changed sign)."""
        if self._state in (LEFT_1, RIGHT_1) and self._in_lane_valid(v):
            return False                                  # phase 1 ends before the marking (docs/controller.md)
        m = v["toMarking_M"]
        return m >= 0 if self._state in LEFT_CHANGE else m < 0

    def _still_safe(self, v: dict[str, float]) -> bool:
        left = self._state in LEFT_CHANGE
        if not self.rear_safe("left" if left else "right", v, abort=True):
            return False
        if self._state in (LEFT_1, RIGHT_1) and self._in_lane_valid(v):
            ahead = v["dist_LL"] if left else v["dist_RR"]
        else:
            ahead = v["dist_L"] if left else v["dist_R"]   # on the marking: the lane beyond it
        return ahead >= self.lookout.ahead_min

    def _abort(self, v: dict[str, float]) -> None:
        """Back into the lane the change started from: in phase 1 lane keeping does it (the in-lane system still
        sees that lane); on the marking, the mirror change's phase 2 aims at the lane on this side of it."""
        self._aborts += 1
        if self._state in (LEFT_1, RIGHT_1) and self._in_lane_valid(v):
            self._state = KEEP
        else:
            self._state = RIGHT_2 if self._state in LEFT_CHANGE else LEFT_2   # L4 sets its gain
        self.occupancy.restart()                        # both lanes prove clear afresh, as after a change

    # --- L3: pull out behind the leader -------------------------------------------------------------------------
    def _change_speed_limit(self, v: dict[str, float], side: str = "") -> float:
        """L3's limit [m/s] during a change (or, with `side`, during one about to start that way), and L5's."""
        if not side:
            return min(self._pull_out_limit(v), self.stop_speed(v))
        return self._pull_out_limit(v, side)

    def _pull_out_limit(self, v: dict[str, float], side: str = "") -> float:
        if self._state == KEEP and not side:
            return self.params.no_slow_down
        left = self._state in LEFT_CHANGE if not side else side == "left"
        if self._state == KEEP or (self._state in (LEFT_1, RIGHT_1) and self._in_lane_valid(v)):
            return self.follow_speed(v["dist_MM"])       # still in the lane it leaves
        m = v["toMarking_M"]
        leaving_clear = m > self.lookout.clear_margin if left else m < -self.lookout.clear_margin
        if leaving_clear:
            return self.params.no_slow_down
        # on the marking: the lane it leaves lies right of it for a change to the left, left of it for one right
        return self.follow_speed(v["dist_R"] if left else v["dist_L"])

    # --- L5: stop in time -------------------------------------------------------------------------------------------
    def stop_speed(self, v: dict[str, float]) -> float:
        """L5's limit [m/s]: the speed from which the host stops behind the car ahead if that car brakes to a
        standstill (no limit without a car ahead in the in-lane system's view)."""
        p, gap = self.lookout, v["dist_MM"]
        last, self._last_mm = self._last_mm, None
        if not p.stop_in_time or not self._in_lane_valid(v) or gap >= GAP_MAX:
            return self.params.no_slow_down
        self._last_mm = gap
        closing = (last - gap) / p.frame if last is not None and abs(last - gap) <= p.gap_jump else 0.0
        lead = max(0.0, self._speed - closing)
        room = gap - p.car_length - p.stop_margin + lead * lead / (2.0 * p.lead_decel)
        if room <= 0:
            self._stop_limit = 0.0
            return 0.0
        b, tau = p.stop_decel, p.stop_delay
        self._stop_limit = b * (-tau + math.sqrt(tau * tau + 2.0 * room / b))
        return self._stop_limit
