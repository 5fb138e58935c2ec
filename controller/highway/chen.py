"""The Chen controller: DeepDriving's hand-written driver, from the affordance indicators to a TORCS command.

Rules, constants and sign conventions: docs/controller.md (numbered rules 1-7 below). Indicator meanings:
docs/affordances.md. Runs at 10 Hz of simulated time; the timers count frames.

Signs: `angle > 0` means the car points to the right of the road, so a positive (left) steer corrects it.
`center_line` is the car's offset from its target centre line, positive when the car is left of it, so a
positive `center_line` steers right. Steer is positive to the left.

Depends only on numpy and the highway's declaration (docs/architecture.md).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from core.worlds.highway import (
    EDGE_MARKING,
    IN_LANE_SPAN,
    INACTIVE,
    INDICATORS,
    NEIGHBOUR_LANE,
    NEIGHBOUR_OCCUPIED,
    STEER_LOCK_RAD,
    Action,
)

# Lane-change states: keeping a lane, or phase 1 / phase 2 of a change to the left or to the right.
KEEP = "keep"
LEFT_1, LEFT_2 = "left-1", "left-2"
RIGHT_1, RIGHT_2 = "right-1", "right-2"
STATES = (KEEP, LEFT_1, LEFT_2, RIGHT_1, RIGHT_2)


class LaneOccupancy:
    """Rule 1's two timers: frames since a car was last seen ahead within `occupied_gap` in the left / right lane.

    A car counts only when two successive frames see it, so one noisy estimate does not block a lane. Its own
    object so that the benchmark can run rule 1 on the true gaps beside a driver's controller
    (drivestudio/worlds/highway/benchmark/clips.py)."""

    def __init__(self, occupied_gap: float, pre_dist: float):
        self.occupied_gap = occupied_gap
        self.left = self.right = 0                 # [frames] clear frames in a row
        self.restarts = 0                          # restart() calls: a change started (or the lookout aborted one)
        self._pre_L = self._pre_R = pre_dist

    def update(self, dist_LL: float, dist_RR: float) -> None:
        if self._pre_L < self.occupied_gap and dist_LL < self.occupied_gap:
            self.left = 0
        else:
            self.left += 1
        if self._pre_R < self.occupied_gap and dist_RR < self.occupied_gap:
            self.right = 0
        else:
            self.right += 1
        self._pre_L, self._pre_R = dist_LL, dist_RR

    def restart(self) -> None:
        """Both lanes must prove clear afresh (rule 2, after a change starts)."""
        self.left = self.right = 0
        self.restarts += 1

    def timer(self, side: str) -> int:
        return self.left if side == "left" else self.right


@dataclass(frozen=True)
class ChenParams:
    """Every constant of docs/controller.md, named. Frames are 0.1 s (10 Hz)."""

    # steering
    road_width: float = 8.0                   # [m] divides center_line into an angle-like term
    steer_lock: float = STEER_LOCK_RAD        # [rad] steering gain divisor: the wheel angle at steer = 1
    # rule 1: lane occupancy
    timer_set: int = 60                       # [frames] clear frames before a neighbour lane counts as clear
    timer_set_two_lane_after_change: int = 30  # [frames] the same, on two lanes after an overtaking change
    occupied_gap: float = NEIGHBOUR_OCCUPIED  # [m] a neighbour lane is occupied by a car ahead closer than this
    pre_dist_start: float = 60.0              # [m] pre_dist_L/R before the first frame
    # rule 2: overtake or follow
    follow_gap: float = 15.0                  # [m] dist_MM below this: overtake or follow
    v_max: float = 20.0                       # [m/s] follow curve: speed far behind the leader
    follow_c: float = 2.772                   # [1/s] follow curve: slow_down = v_max (1 - exp(-c/v_max dist - d))
    follow_d: float = -0.693                  # [-] follow curve offset (0 m/s at 5 m)
    no_slow_down: float = math.inf            # [m/s] slow_down when not following: no limit
    left_lane_exists: float = -NEIGHBOUR_LANE  # [m] toMarking_LL above this: a lane to the left exists
    right_lane_exists: float = NEIGHBOUR_LANE  # [m] toMarking_RR below this: a lane to the right exists
    steer_trend_bound: float = 0.2            # [-] |steer_trend| below this to start a change (not on 2 lanes)
    steer_history: int = 5                    # [frames] steering commands summed into steer_trend
    # rule 4: lane keeping
    in_lane_span: float = IN_LANE_SPAN        # [m] in-lane estimate trusted when -toMarking_ML + toMarking_MR < this
    coe_keep: float = 1.5                     # [-] steering divisor, in-lane
    coe_keep_near_marking: float = 0.4        # [-] steering divisor, in-lane and toMarking_M < near_marking
    near_marking: float = 1.0                 # [m] toMarking_M below this: close to a marking, steer harder
    coe_on_marking: float = 0.3               # [-] steering divisor, on-marking estimate only
    edge_marking: float = EDGE_MARKING        # [m] |toMarking_L/R| beyond this: the edge's inactive 7 (ours)
    # rule 5: lane change
    coe_change: float = 6.0                   # [-] steering divisor, phase 1
    coe_change_phase_2: float = 20.0          # [-] steering divisor, phase 2
    change_marking_outer: float = 5.0         # [m] phase test: toMarking_L > -5 (right: toMarking_R < 5)
    change_marking_m: float = 1.5             # [m] phase test: toMarking_M < 1.5 (right: toMarking_M > -1.5)
    # rule 6: steering shape
    boost_above: float = 0.1                  # [-] left steer above this is reshaped ...
    boost_slope: float = 2.5                  # [-] ... as steer *= boost_slope * steer + boost_offset
    boost_offset: float = 0.75                # [-]
    # rule 7: speed
    v_cruise: float = 20.0                    # [m/s] desired speed when `fast` or going straight
    trend_slowdown: float = 4.5               # [m/s] desired speed lost per unit of |steer_trend|
    v_min: float = 10.0                       # [m/s] floor of the desired speed (before slow_down)
    accel_gain: float = 0.2                   # [1/(m/s)] accel = min(1, accel_gain (desired - speed + accel_bias))
    accel_bias: float = 1.0                   # [m/s]
    brake_gain: float = 0.1                   # [1/(m/s)] brake = min(1, brake_gain (speed - desired))


class ChenController:
    """DeepDriving's driver for `lanes` lanes: two-lane rules on 2, three-lane rules otherwise.

    On 4 lanes "prefer the centre" keeps the car off the edge lanes; on 1 lane no lane change happens, since
    toMarking_LL / toMarking_RR read their inactive -9.5 / 9.5 (no lane on either side).
    """

    def __init__(self, lanes: int, params: ChenParams = ChenParams()):
        if isinstance(lanes, bool) or not isinstance(lanes, (int, np.integer)) or lanes < 1:
            raise ValueError(f"lanes must be a positive integer, got {lanes!r}")
        self.lanes = int(lanes)
        self.two_lane = self.lanes == 2
        self.params = params
        self.reset()

    def reset(self) -> None:
        p = self.params
        self._state = KEEP
        self._coe_steer = p.coe_keep
        self.occupancy = LaneOccupancy(p.occupied_gap, p.pre_dist_start)
        self._timer_set = p.timer_set
        self._steers: deque[float] = deque([0.0] * p.steer_history, maxlen=p.steer_history)
        # no in-lane estimate seen yet: the inactive values (a tie, so the lane right of the marking is taken)
        self._pre_ML = INACTIVE["toMarking_ML"]
        self._pre_MR = INACTIVE["toMarking_MR"]
        self._lane_changes = 0
        self._change_reason = ""

    # --- what others read ---------------------------------------------------------------------------------
    @property
    def state(self) -> str:
        """Lane-change state: "keep", "left-1", "left-2", "right-1" or "right-2" (phase 1 / phase 2)."""
        return self._state

    @property
    def lane_changes_started(self) -> int:
        return self._lane_changes

    @property
    def change_reason(self) -> str:
        """What started the last lane change: "overtake" (rule 2), "preference" (rule 3) or "forced"."""
        return self._change_reason

    @property
    def left_clear(self) -> bool:
        """Rule 1: no car within occupied_gap in the left lane for more than timer_set frames."""
        return self.occupancy.left > self._timer_set

    @property
    def right_clear(self) -> bool:
        return self.occupancy.right > self._timer_set

    @property
    def timer_set(self) -> int:
        """[frames] the clear frames rule 1 asks for now (fewer on two lanes after an overtake)."""
        return self._timer_set

    @property
    def steer_trend(self) -> float:
        """Sum of the last steer_history steering commands."""
        return float(sum(self._steers))

    def begin_lane_change(self, direction: str) -> None:
        """Start a lane change now, whatever the lane timers say (the data-collection expert's forced changes).
        The caller checks that the target lane exists; the state machine then runs as for any change."""
        if direction not in ("left", "right"):
            raise ValueError(f"direction must be 'left' or 'right', got {direction!r}")
        if self._state == KEEP:
            self._begin_change(LEFT_1 if direction == "left" else RIGHT_1, overtaking=False, reason="forced")

    # --- one frame ------------------------------------------------------------------------------------------
    def act(self, indicators, speed: float) -> Action:
        """One 10 Hz frame: the 14 indicators in canonical order (13 accepted, then fast = 0), speed [m/s]."""
        v = self._read(indicators)
        self.occupancy.update(v["dist_LL"], v["dist_RR"])
        trend = self.steer_trend  # of the previous frames: this frame's command is not known yet
        slow_down = self.params.no_slow_down
        if self._state == KEEP:
            if v["dist_MM"] < self.params.follow_gap:
                slow_down = self._overtake_or_follow(v, trend)
            else:
                self._prefer_lane(v, trend)
        center_line = self._target(v)
        slow_down = min(slow_down, self._change_speed_limit(v))
        steer = self._steer(v["angle"], center_line)
        self._steers.append(steer)
        accel, brake = self._speed_control(v["fast"], float(speed), slow_down)
        return Action(steer, accel, brake)

    @staticmethod
    def _read(indicators) -> dict[str, float]:
        values = np.asarray(indicators, dtype=np.float64).reshape(-1)
        if values.size == len(INDICATORS) - 1:
            values = np.append(values, 0.0)  # the paper's 13: no `fast`
        if values.size != len(INDICATORS):
            raise ValueError(f"expected {len(INDICATORS)} (or {len(INDICATORS) - 1}) indicators, got {values.size}")
        return dict(zip(INDICATORS, values.tolist()))

    # --- rules 2 and 3: when to change lane -----------------------------------------------------------------
    def _left_exists(self, v: dict[str, float]) -> bool:
        return v["toMarking_LL"] > self.params.left_lane_exists

    def _right_exists(self, v: dict[str, float]) -> bool:
        return v["toMarking_RR"] < self.params.right_lane_exists

    def _may_turn_left(self, trend: float, bounded: bool) -> bool:
        # not while still turning right (trend < 0), nor, when bounded, while already turning left hard
        return trend >= 0 and (not bounded or trend < self.params.steer_trend_bound)

    def _may_turn_right(self, trend: float, bounded: bool) -> bool:
        return trend <= 0 and (not bounded or trend > -self.params.steer_trend_bound)

    # --- what a subclass may add (controller/highway/lookout.py); here they change nothing ---------------------
    def _target_safe(self, side: str, v: dict[str, float]) -> bool:
        """May a change to `side` ("left" or "right") start now, besides rules 1-3? The paper's driver: always."""
        return True

    def _change_speed_limit(self, v: dict[str, float]) -> float:
        """A speed limit [m/s] on top of rules 2 and 7, checked after the state machine ran. Here: none."""
        return self.params.no_slow_down

    def _overtake_or_follow(self, v: dict[str, float], trend: float) -> float:
        """Rule 2 (dist_MM < follow_gap): start an overtake if a neighbour lane is clear, else follow.

        Returns slow_down [m/s]."""
        bounded = not self.two_lane  # the two-lane driver has no 0.2 bound on an overtake
        if self._left_exists(v) and self.left_clear and self._may_turn_left(trend, bounded) and \
                self._target_safe("left", v):
            self._begin_change(LEFT_1, overtaking=True)
        elif self._right_exists(v) and self.right_clear and self._may_turn_right(trend, bounded) and \
                self._target_safe("right", v):
            self._begin_change(RIGHT_1, overtaking=True)
        else:
            return self.follow_speed(v["dist_MM"])
        return self.params.no_slow_down

    def follow_speed(self, dist_MM: float) -> float:
        """Rule 2, follow: the optimal-velocity curve, 0 m/s at 5 m, 10 at 10 m, 15 at 15 m, never below 0."""
        p = self.params
        return max(0.0, p.v_max * (1.0 - math.exp(-p.follow_c / p.v_max * dist_MM - p.follow_d)))

    def _prefer_lane(self, v: dict[str, float], trend: float) -> None:
        """Rule 3 (dist_MM >= follow_gap): three lanes prefer the centre, two lanes the right lane.

        A move needs a lane on the far side too, so an inactive in-lane system (LL = -9.5 and RR = 9.5 at
        once, or a one-lane road) never starts one. The steer-trend bound applies as for an overtake: a
        preference is never worth starting a change while the car is turning."""
        left, right = self._left_exists(v), self._right_exists(v)
        if self.two_lane:
            if right and self.right_clear and self._may_turn_right(trend, bounded=True) and \
                    self._target_safe("right", v):
                self._begin_change(RIGHT_1, overtaking=False)
        elif left and not right and self.left_clear and self._may_turn_left(trend, bounded=True):
            if self._target_safe("left", v):
                self._begin_change(LEFT_1, overtaking=False)   # in the rightmost lane: move towards the centre
        elif right and not left and self.right_clear and self._may_turn_right(trend, bounded=True):
            if self._target_safe("right", v):
                self._begin_change(RIGHT_1, overtaking=False)  # in the leftmost lane: move towards the centre

    def _begin_change(self, state: str, overtaking: bool, reason: str = "") -> None:
        self._state = state
        self._coe_steer = self.params.coe_change
        self._lane_changes += 1
        self._change_reason = reason or ("overtake" if overtaking else "preference")
        # both lanes must prove clear afresh before the next change (rule 2 resets both timers)
        self.occupancy.restart()
        if self.two_lane:
            # after an overtake the two-lane driver returns to the right lane sooner; back in it, the usual wait
            self._timer_set = self.params.timer_set_two_lane_after_change if overtaking else self.params.timer_set

    # --- rules 4 and 5: where to steer ----------------------------------------------------------------------
    def _in_lane_valid(self, v: dict[str, float]) -> bool:
        return -v["toMarking_ML"] + v["toMarking_MR"] < self.params.in_lane_span

    def _near_left_marking(self, v: dict[str, float]) -> bool:
        """On a marking with a lane left of it: the on-marking test of a change to the left."""
        return v["toMarking_L"] > -self.params.change_marking_outer and v["toMarking_M"] < self.params.change_marking_m

    def _near_right_marking(self, v: dict[str, float]) -> bool:
        return v["toMarking_R"] < self.params.change_marking_outer and v["toMarking_M"] > -self.params.change_marking_m

    def _target(self, v: dict[str, float]) -> float:
        """center_line [m] for this frame; runs the lane-change state machine and sets coe_steer."""
        if self._state == LEFT_1:
            return self._change_phase_1(v, LEFT_2, "toMarking_LL", "toMarking_ML", "toMarking_L",
                                        self._near_left_marking)
        if self._state == RIGHT_1:
            return self._change_phase_1(v, RIGHT_2, "toMarking_RR", "toMarking_MR", "toMarking_R",
                                        self._near_right_marking)
        if self._state == LEFT_2 and self._near_left_marking(v):
            return (v["toMarking_L"] + v["toMarking_M"]) / 2
        if self._state == RIGHT_2 and self._near_right_marking(v):
            return (v["toMarking_R"] + v["toMarking_M"]) / 2
        if self._state != KEEP:
            # phase 2 over (its on-marking test failed): lane keeping steers from this very frame, rather
            # than reusing the last target for one frame as the original did
            self._state = KEEP
        return self._lane_keeping(v)

    def _change_phase_1(self, v, phase_2: str, outer: str, inner: str, marking: str, near_marking) -> float:
        """Rule 5, phase 1: aim at the neighbour lane's centre from the in-lane system, with coe_change."""
        if self._in_lane_valid(v):
            center_line = (v[outer] + v[inner]) / 2
            if near_marking(v):  # both systems see the target lane: average their estimates
                center_line = (center_line + (v[marking] + v["toMarking_M"]) / 2) / 2
            return center_line
        # the in-lane system gave out while crossing: phase 2 aims by the marking, gently
        self._state = phase_2
        self._coe_steer = self.params.coe_change_phase_2
        return (v[marking] + v["toMarking_M"]) / 2

    def _lane_keeping(self, v: dict[str, float]) -> float:
        """Rule 4: the in-lane estimate when it is trusted, else the lane beside the marking the car is on."""
        p = self.params
        if self._in_lane_valid(v):
            self._pre_ML, self._pre_MR = v["toMarking_ML"], v["toMarking_MR"]
            self._coe_steer = p.coe_keep_near_marking if v["toMarking_M"] < p.near_marking else p.coe_keep
            return (v["toMarking_ML"] + v["toMarking_MR"]) / 2
        self._coe_steer = p.coe_on_marking
        # last seen nearer its right marking, the car drifted across it: its lane lies left of this marking
        lane_on_left = -self._pre_ML > self._pre_MR
        # never aim at the far side of a road edge (toMarking_L/R read their inactive -7/7 there)
        left_gone, right_gone = v["toMarking_L"] < -p.edge_marking, v["toMarking_R"] > p.edge_marking
        if left_gone and right_gone:
            # wide lanes, far outside an edge: the neighbour marking reads beyond the threshold too. The marking
            # the car is on says where the road is: right of the left edge (M > 0), left of the right edge (M < 0)
            lane_on_left = v["toMarking_M"] < 0
        elif left_gone:
            lane_on_left = False
        elif right_gone:
            lane_on_left = True
        side = v["toMarking_L"] if lane_on_left else v["toMarking_R"]
        return (side + v["toMarking_M"]) / 2

    # --- rule 6: steering -----------------------------------------------------------------------------------
    def _steer(self, angle: float, center_line: float) -> float:
        p = self.params
        steer = (angle - center_line / p.road_width) / p.steer_lock / self._coe_steer
        if self._state == KEEP and self._coe_steer > 1 and steer > p.boost_above:
            steer *= p.boost_slope * steer + p.boost_offset
        return float(np.clip(steer, -1.0, 1.0))  # the trend then sums commands actually sent

    # --- rule 7: speed --------------------------------------------------------------------------------------
    def _speed_control(self, fast: float, speed: float, slow_down: float) -> tuple[float, float]:
        p = self.params
        trend = self.steer_trend  # now including this frame's command, as it is known by here
        # `fast` is a 0/1 flag; a network's estimate counts from one half
        desired = p.v_cruise if fast >= 0.5 else p.v_cruise - p.trend_slowdown * abs(trend)
        desired = min(max(desired, p.v_min), slow_down)
        if desired >= speed:
            return min(1.0, p.accel_gain * (desired - speed + p.accel_bias)), 0.0
        return 0.0, min(1.0, p.brake_gain * (speed - desired))
