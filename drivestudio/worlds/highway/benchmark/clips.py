"""Why it crashed: a short clip of every collision and off-road event, and the indicator most to blame.

A route keeps a ring buffer of its last CLIP_BEFORE seconds of StepRecords. When the host car starts touching
another car, or its centre starts being beyond a road edge, the buffer (and the next CLIP_AFTER seconds) becomes an
mp4: each frame is the box overlay of truth against estimate (drivestudio/worlds/highway/overlays.py,
docs/overlays.md) over a
text panel with the Chen controller's state and command. The indicator whose error, divided by its error-bar scale
(perception/highway/overlay.py ERROR_SCALE: 0.2 rad, 2 m for the markings, 20 m for the gaps; one lane for lanes_left),
was largest on average over the seconds before the event is named in the panel and in the leaderboard.

The controller's state is read from a shadow controller (the Chen controller, or the lookout controller of the
extended oracle) fed exactly what the driver's controller was fed (the estimate record and the speed): the
controller is deterministic, so the shadow holds the same state whether the driver ran in this process or in
another one over the bridge. Its command is checked against the action the driver sent every step (`agreed`).

For a collision the panel also names the controller rule that led to it (`rule`): the rule that started the lane
change the host car was in (rule 2's overtake or rule 3's lane preference) with what the target lane held beside
and behind the host at that moment and the safe gap the lookout would have asked for, or the follow law of rule 2
when the host ran into the car ahead in its lane.

A lane change's collision also gets a `cause`, from rule 1 run on the true gaps beside the driver's controller
(the shadow's `truth_occupancy`, restarted whenever the driver's is): "blind spot" when the true gaps had kept the
target lane clear for as long as rule 1 asks too, so the controller on exact indicators would have started the same
change on the same path (a car beside or behind, which DeepDriving's indicators do not describe); "misread" when
the true gaps had a car ahead in that lane within rule 1's time, so only the estimate made the lane look free.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from controller.highway import ChenController
from controller.highway.chen import KEEP, LaneOccupancy
from controller.highway.lookout import LookoutController, safe_gap
from core.worlds.highway import HIGHWAY, INDEX, INDICATORS, PAPER_INDICATORS, REAR, REAR_RANGE
from drivestudio.outputs import VideoWriter, write_json
from drivestudio.worlds.highway.benchmark.models import ModelSpec
from drivestudio.worlds.highway.benchmark.replay import REPLAY_BEFORE, replay_scenario
from drivestudio.worlds.highway.benchmark.suite import Route
from drivestudio.worlds.highway.drivers import act_on, make_controller
from drivestudio.worlds.highway.overlays import overlay_observation
from perception.highway.overlay import ERROR_SCALE

if TYPE_CHECKING:
    from sim.highway.traffic import CarStates
    from sim.highway.world import Observation

PANEL_HEIGHT = 206
LANES_LEFT_SCALE = 1.0     # [lanes] the error of lanes_left that fills an error bar
GAP_RELEVANT = 30.0        # [m] gaps are compared below this: the controller reacts to cars within 20 m (rule 1)
                           # and 15 m (rule 2; its follow speed is 97 % of v_max at 30 m), so 60 read as 40 is no fault
CHANGE_BLAME = 2.0         # [s] a lane change over longer than this before a collision is not its cause (as the
                           # route metrics' CHANGE_MARGIN)
_I_LANES_LEFT_EST = HIGHWAY.estimate_names.index("lanes_left")
_I_REAR_EST = [HIGHWAY.estimate_names.index(n) for n in REAR]
_I_SPEED, _I_LANES = HIGHWAY.index("speed"), HIGHWAY.index("lanes")


@dataclass
class Entry:
    """One step in the ring buffer: the observation, the command applied on it, the estimate and the controller
    state the command came from."""

    obs: Observation
    action: np.ndarray
    estimate: np.ndarray
    control: dict | None
    cars: CarStates | None = None   # the cars the observation was made of (speeds and models: for a replay)


@dataclass
class _Pending:
    event: str
    index: int                     # the route's clip number
    before: list                   # the clip's seconds before the event
    history: list                  # the replay's (replay.py: longer)
    after: list = field(default_factory=list)


class ShadowController:
    """The driver's controller, replayed on the world side from the estimates the driver reported."""

    def __init__(self, lookout: bool = False, exact: bool = False):
        self.ctrl: ChenController | None = None
        self.exact = exact
        self.truth_occupancy: LaneOccupancy | None = None   # rule 1 on the true gaps, restarted as the driver's
        self.lookout = lookout
        self.agreed = True

    def __call__(self, rec) -> dict:
        record = rec.obs.record
        lanes = int(record[_I_LANES])
        c = self.ctrl
        if c is None or c.lanes != lanes:
            c = self.ctrl = make_controller(lanes, self.lookout, self.exact)
            self.truth_occupancy = LaneOccupancy(c.params.occupied_gap, c.params.pre_dist_start)
        assert self.truth_occupancy is not None
        truth = rec.obs.truth.indicators
        self.truth_occupancy.update(float(truth[INDEX["dist_LL"]]), float(truth[INDEX["dist_RR"]]))
        state, timer_set, restarts = c.state, c.timer_set, c.occupancy.restarts
        estimate = np.asarray(rec.estimate, dtype=np.float64)
        action = act_on(c, estimate, float(record[_I_SPEED])).as_array()
        same = bool(np.allclose(action, np.asarray(rec.action, dtype=np.float64), rtol=0, atol=1e-9))
        self.agreed &= same
        dist_mm = float(np.nan_to_num(estimate[INDEX["dist_MM"]], nan=0.0))
        follow = c.follow_speed(dist_mm) if c.state == "keep" and dist_mm < c.params.follow_gap else None
        out = {"state": c.state, "left_clear": c.left_clear, "right_clear": c.right_clear,
               "steer_trend": round(c.steer_trend, 4), "follow_mps": None if follow is None else round(follow, 2),
               "reason": c.change_reason, "agrees": same}
        if state == KEEP and c.state != KEEP:   # a change started: was its lane clear by rule 1 on the truth?
            side = c.state.split("-")[0]
            out["truth_clear_frames"] = [self.truth_occupancy.timer(side), timer_set]
        if c.occupancy.restarts != restarts:
            self.truth_occupancy.restart()
        if isinstance(c, LookoutController):
            out.update(refused=c.refused, aborts=c.aborts)
        return out


def largest_error(entries: list[Entry]) -> dict | None:
    """The indicator whose error divided by its error-bar scale was largest on average over `entries`
    (None when the estimates are exact: the oracle)."""
    rows = [(e.obs.truth, e.estimate) for e in entries if e.estimate is not None and
            np.isfinite(e.estimate[:len(PAPER_INDICATORS)]).all()]
    if not rows:
        return None
    names = list(PAPER_INDICATORS)
    truth = np.array([t.indicators[:len(names)] for t, _ in rows])
    est = np.array([e[:len(names)] for _, e in rows])
    gaps = [i for i, n in enumerate(names) if n.startswith("dist_")]
    truth[:, gaps] = np.minimum(truth[:, gaps], GAP_RELEVANT)
    est[:, gaps] = np.minimum(est[:, gaps], GAP_RELEVANT)
    err = np.abs(est - truth)
    scales = np.array([ERROR_SCALE[n] for n in names])
    if all(np.isfinite(e[_I_LANES_LEFT_EST]) for _, e in rows):
        names.append("lanes_left")
        ll = np.abs(np.array([e[_I_LANES_LEFT_EST] - t.lanes_left for t, e in rows]))
        err = np.column_stack([err, ll])
        scales = np.append(scales, LANES_LEFT_SCALE)
    norm = err / scales
    mean = norm.mean(axis=0)
    if not mean.max() > 0:
        return None
    order = np.argsort(-mean, kind="stable")
    return {"indicator": names[order[0]], "normalised": round(float(mean[order[0]]), 3),
            "mean_error": round(float(err[:, order[0]].mean()), 3), "peak_normalised": round(float(norm[:, order[0]]
                                                                                                   .max()), 3),
            "ranking": [[names[i], round(float(mean[i]), 3)] for i in order[:4]]}


def describe_contact(entries: list[Entry], track) -> str:
    """Who touched whom at a collision: the nearest other car, where it was and whether it or the host changed
    lanes in the second before."""
    last = entries[-1].obs.truth
    cars = np.asarray(last.cars, dtype=np.float64).reshape(-1, 5)
    if not len(cars):
        return "no other car near"
    ego_s, ego_d = float(last.ego[3]), float(last.ego[4])
    gaps = track.gap(ego_s, cars[:, 3])
    lateral = cars[:, 4] - ego_d
    i = int(np.argmin(np.hypot(gaps, lateral * 2.0)))
    gap, lat = float(gaps[i]), float(lateral[i])
    host_lane, car_lane = track.lane_of(ego_d), track.lane_of(float(cars[i, 4]))
    where = "ahead" if gap > 1.0 else "behind" if gap < -1.0 else "alongside"
    side = "left" if lat > 0 else "right"
    text = f"a car {abs(gap):.1f} m {where}, {abs(lat):.1f} m to the {side}"
    text += " in the host's lane" if car_lane == host_lane else \
        f" in lane {car_lane + 1} (host in lane {host_lane + 1}; 1 = leftmost)"
    back = entries[max(0, len(entries) - 11)].obs.truth   # a second earlier
    back_cars = np.asarray(back.cars, dtype=np.float64).reshape(-1, 5)
    changed = []
    if track.lane_of(float(back.ego[4])) != host_lane or abs(float(back.ego[4]) - ego_d) > 1.0:
        changed.append("the host was changing lanes")
    if len(back_cars) == len(cars) and (track.lane_of(float(back_cars[i, 4])) != car_lane
                                        or abs(float(back_cars[i, 4]) - float(cars[i, 4])) > 1.0):
        changed.append("the other car was changing lanes")
    if where == "ahead" and car_lane == host_lane and not changed:
        changed.append("the host ran into it")
    elif where == "behind" and not changed:
        changed.append("it ran into the host")
    return text + ("; " + ", ".join(changed) if changed else "")


def rear_text(rear, speed: float) -> str:
    """The rear labels as a line: "left 3.2 m closing +4.1 m/s (safe gap 11.2 m), right none within 100 m", the
    safe gap (the lookout's L1) for a host at `speed` [m/s]."""
    v = dict(zip(REAR, np.asarray(rear, dtype=np.float64).tolist()))
    parts = []
    for side, k in (("left", "L"), ("right", "R")):
        gap, closing = v[f"dist_{k}B"], v[f"closing_{k}B"]
        parts.append(f"{side} none within {REAR_RANGE:.0f} m" if gap >= REAR_RANGE else
                     f"{side} {gap:.1f} m closing {closing:+.1f} m/s (safe gap {safe_gap(closing, speed):.1f} m)")
    return ", ".join(parts)


def rule_at_fault(entries: list[Entry], dt: float) -> str:
    """The controller rule that led to a collision: the rule that started the lane change the host was in (with
    what the target lane held beside and behind at that moment), or the follow law when it kept its lane."""
    return fault(entries, dt)[0]


def fault(entries: list[Entry], dt: float) -> tuple[str, str]:
    """rule_at_fault's text and the cause: "blind spot" or "misread" for a lane change (the module's docstring),
    "keeping" when no change led to the collision, "" when the change started before the buffer."""
    states = [e.control["state"] if e.control else "keep" for e in entries]
    t_event = float(entries[-1].obs.t)
    for i in range(len(entries) - 1, 0, -1):
        if states[i] in ("left-1", "right-1") and states[i - 1] == "keep":
            done = next((j for j in range(i, len(entries)) if states[j] == "keep"), None)
            if done is not None and t_event - float(entries[done].obs.t) > CHANGE_BLAME:
                break   # that change was over well before the collision
            e = entries[i]
            side = states[i].split("-")[0]
            rule = {"overtake": "rule 2 (overtake)", "preference": "rule 3 (lane preference)"}.get(
                (e.control or {}).get("reason", ""), "a forced change")
            k = "L" if side == "left" else "R"
            rear = dict(zip(REAR, e.obs.truth.rear.tolist()))
            gap, closing = rear[f"dist_{k}B"], rear[f"closing_{k}B"]
            held = f"nothing within {REAR_RANGE:.0f} m" if gap >= REAR_RANGE else \
                (f"a car {gap:.1f} m behind closing at {closing:+.1f} m/s (safe gap "
                 f"{safe_gap(closing, float(e.obs.truth.speed)):.1f} m)")
            ahead = e.obs.truth.indicators[INDEX["dist_LL" if side == "left" else "dist_RR"]]
            text = (f"{rule} started a change to the {side} {t_event - float(e.obs.t):.1f} s before; beside and "
                    f"behind in that lane: {held}; ahead in it: {ahead:.1f} m")
            clear, needed = (e.control or {}).get("truth_clear_frames", (None, None))
            cause = "" if clear is None else "blind spot" if clear > needed else "misread"
            return text, cause
    if states[-1] != "keep":
        return f"a lane change ({states[-1]}) that started more than {len(entries) * dt:.0f} s before", ""
    return "lane keeping (rule 4) and the follow law (rule 2): no lane change in the seconds before", "keeping"


CAUSE_TEXT = {"blind spot": "on the true gaps rule 1 counted that lane clear too: the controller's blind spot",
              "misread": "on the true gaps that lane was taken: only the estimate made it look free",
              "keeping": "", "": ""}


class ClipRecorder:
    """on_step callback of a route: the ring buffer, event detection and the clips (at most opts.clips)."""

    def __init__(self, world, route: Route, model: ModelSpec, clip_dir: Path | None, opts):
        self.world, self.route, self.model = world, route, model
        self.dir = clip_dir
        self.limit = opts.clips if clip_dir is not None else 0
        self.before_n = int(round(opts.clip_before / world.dt))
        self.after_n = int(round(opts.clip_after / world.dt))
        self.buffer: deque = deque(maxlen=max(self.before_n, int(round(REPLAY_BEFORE / world.dt))) + 1)
        self.shadow = ShadowController(model.lookout, model.exact)
        self.pending: list[_Pending] = []
        self.clips: list[dict] = []
        self.skipped = 0
        self._events = 0
        self._was = {"collision": False, "off-road": False}

    @property
    def agreed(self) -> bool:
        return self.shadow.agreed

    def __call__(self, rec) -> None:
        self._push(Entry(rec.obs, np.asarray(rec.action, dtype=np.float64),
                         np.asarray(rec.estimate, dtype=np.float64), self.shadow(rec), self.world.last_cars))

    def _push(self, entry: Entry) -> None:
        self.buffer.append(entry)
        for p in list(self.pending):
            p.after.append(entry)
            if len(p.after) >= self.after_n:
                self._write(p)
        obs = entry.obs
        for event, now in (("collision", bool(obs.collision)), ("off-road", bool(obs.off_road))):
            if now and not self._was[event]:
                self._events += 1
                if len(self.clips) + len(self.pending) < self.limit:
                    history = list(self.buffer)
                    self.pending.append(_Pending(event, self._events, history[-(self.before_n + 1):], history))
                else:
                    self.skipped += 1
            self._was[event] = now

    def finish(self, last_obs) -> list[dict]:
        """The route's last observation (which no action followed) may hold an event too; then every clip still
        waiting for its after-seconds is written with what there is."""
        self._push(Entry(last_obs, np.full(3, np.nan), np.full(len(HIGHWAY.estimate_names), np.nan), None,
                         self.world.last_cars))
        for p in list(self.pending):
            self._write(p)
        return self.clips

    # --- writing ---------------------------------------------------------------------------------------------
    def _write(self, p: _Pending) -> None:
        self.pending.remove(p)
        event_entry = p.before[-1]
        t = float(event_entry.obs.t)
        blame = largest_error(p.before)
        info = {"event": p.event, "t": round(t, 1), "route": self.route.name,
                "largest_error": blame, "control": event_entry.control,
                "command": None if not np.isfinite(event_entry.action).all() else
                [round(float(v), 4) for v in event_entry.action]}
        if p.event == "collision":
            info["contact"] = describe_contact(p.before, self.world.track)
            info["rule"], info["cause"] = fault(p.before, self.world.dt)
            info["scenario"], why = self._write_replay(p, t)
            if why:
                info["scenario_skipped"] = why
        else:
            d = float(event_entry.obs.truth.ego[4])
            info["contact"] = f"left the road over the {'left' if d > 0 else 'right'} edge"
        name = f"{self.route.name}-{p.index:02d}-{p.event}-t{t:06.1f}s.mp4"
        assert self.dir is not None   # clips are recorded only with a clip folder (limit 0 otherwise)
        writer = VideoWriter(self.dir / name)
        try:
            for entry in p.before + p.after:
                writer.write(self.frame(entry, t, info))
            writer.close()
        except BaseException:
            writer.abort()
            raise
        info["file"] = name
        self.clips.append(info)

    def _write_replay(self, p: _Pending, t: float) -> tuple[str | None, str]:
        """CLIP.scenario.json beside the clip: its last seconds as a scripted scenario (replay.py); its file name
        (None when the clip's steps cannot make one) and why not. A start the scenario format refuses (a car caught
        half across the host's lane when the clip begins, as in a merge from alongside) leaves the clip without a
        replay, not the benchmark without its results."""
        from sim.highway.scenario import ScenarioError  # lazy: with the world, already loaded
        from sim.highway.scripted import scripted_from_dict  # lazy: as above
        assert self.dir is not None
        suffix = f"-{p.index:02d}-{p.event}-t{t:06.1f}s"
        name = self.route.name[:64 - len(suffix)] + suffix   # a scenario's name is at most 64 characters
        about = (f"the {REPLAY_BEFORE:g} s before the collision at {t:.1f} s of route {self.route.name} driven by "
                 f"{self.model.label}, replayed from its crash clip")
        obj = replay_scenario(p.history, self.world.track, self.route, t, name, about)
        if obj is None:
            return None, "fewer than two steps before the collision"
        try:
            scripted_from_dict(obj, self.dir)   # only what reads back is written
        except ScenarioError as e:
            return None, str(e)
        write_json(self.dir / f"{name}.scenario.json", obj)
        return f"{name}.scenario.json", ""

    def frame(self, entry: Entry, t_event: float, info: dict, mark: bool = True) -> np.ndarray:
        """One frame of a clip: the overlay over the panel; `mark`: a red border from the event on."""
        obs = entry.obs
        truth = obs.truth
        cars = f"{self.route.cars} cars" if not self.route.scenario else \
            f"{len(self.world.script.actors)} scripted cars, {self.route.cars} AI cars"
        title = f"t {obs.t:5.1f} s  {self.route.name}: {self.route.track}, {truth.lanes} lanes, {cars}"
        if self.model.exact or not np.isfinite(entry.estimate[:len(PAPER_INDICATORS)]).all():
            est, ll, rear = None, None, None
        else:
            est = entry.estimate[:len(INDICATORS)]
            ll = entry.estimate[_I_LANES_LEFT_EST]
            ll = float(ll) if np.isfinite(ll) else None
            rear = entry.estimate[_I_REAR_EST]
        label = self.model.family if self.model.exact else (self.model.family or "estimate")
        top = overlay_observation(obs, est, self.world.track, title, ll, label=label, rear=rear)
        panel = self._panel(entry, obs.t - t_event, info, top.shape[1])
        frame = np.vstack([top, panel])
        if mark and obs.t >= t_event - 1e-6:   # from the event on: a red frame
            cv2.rectangle(frame, (0, 0), (frame.shape[1] - 1, frame.shape[0] - 1), (230, 30, 30), 6)
        return frame

    def _panel(self, entry: Entry, dt_event: float, info: dict, width: int) -> np.ndarray:
        img = np.full((PANEL_HEIGHT, width, 3), 28, np.uint8)
        truth = entry.obs.truth
        c = entry.control
        lines = [(f"{info['event'].upper()} at t = {info['t']:.1f} s ({dt_event:+.1f} s)   model: {self.model.label}",
                  (255, 210, 90))]
        if c is None:
            lines.append(("controller: (the route's last step: no command)", (235, 235, 235)))
        else:
            follow = f"   following: at most {c['follow_mps']:.1f} m/s" if c["follow_mps"] is not None else ""
            lookout = "" if "refused" not in c else \
                f"   lookout: {'refused ' + c['refused'] if c['refused'] else 'no refusal'}, {c['aborts']} aborts"
            lines.append((f"controller: state {c['state']}   left lane clear {'yes' if c['left_clear'] else 'no'}"
                          f"   right lane clear {'yes' if c['right_clear'] else 'no'}   steer trend "
                          f"{c['steer_trend']:+.2f}{follow}{lookout}", (235, 235, 235)))
        a = entry.action
        cmd = "-" if not np.isfinite(a).all() else f"steer {a[0]:+.3f}  accel {a[1]:.2f}  brake {a[2]:.2f}"
        lines.append((f"command: {cmd}   speed {truth.speed:4.1f} m/s   lane {truth.lanes_left + 1} of {truth.lanes} "
                      f"(1 = leftmost)   d {truth.ego[4]:+.2f} m", (235, 235, 235)))
        blame = info["largest_error"]
        if blame is None:
            lines.append(("largest error in the 5 s before: none (exact indicators)", (160, 230, 160)))
        else:
            then = ", ".join(f"{n} {v:.2f}" for n, v in blame["ranking"][1:3])
            lines.append((f"largest error in the 5 s before: {blame['indicator']} (mean |error| "
                          f"{blame['mean_error']:g}, {blame['normalised']:.2f} of its scale; then {then})",
                          (255, 140, 140)))
        lines.append((f"beside and behind (truth): {rear_text(truth.rear, float(truth.speed))}", (235, 235, 235)))
        lines.append((f"contact: {info['contact']}", (235, 235, 235)))
        if info.get("rule"):
            head, _, tail = info["rule"].partition("; ")   # the rule, then what the target lane held
            lines.append((f"rule: {head}" + (";" if tail else ""), (255, 210, 90)))
            if tail:
                lines.append((f"      {tail}", (255, 210, 90)))
            if CAUSE_TEXT.get(info.get("cause", "")):
                lines.append((f"cause: {CAUSE_TEXT[info['cause']]}", (255, 210, 90)))
        for i, (text, colour) in enumerate(lines):
            cv2.putText(img, text[:150], (10, 20 + 22 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv2.LINE_AA)
        return img
