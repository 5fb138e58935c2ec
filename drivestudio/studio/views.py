"""What the page shows of each world, drawn by the world's own overlay code (docs/overlays.md, sim/sidewalk/topdown.py):
the cameras, the top-down view, every label's truth beside the estimate with its error-bar scale (Liu and Wang,
Figure 13), the controller's state, and what a recording stores besides the step (the world's extra columns).

A view's `capture` runs in the loop's thread on every published step and only keeps references (a world's
observations are new objects every step); `images` draws and runs in the encoder's thread.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from controller.sidewalk import SidewalkExpert
from controller.sidewalk.correction import CorrectionParams
from core.worlds.highway import HIGHWAY, INDEX, INDICATORS
from core.worlds.sidewalk import MODES, OPERATIONS, SIDEWALK
from drivestudio.loop import StepRecord
from drivestudio.worlds.highway.overlays import car_gaps
from perception.highway.overlay import ERROR_SCALE, draw_topdown, estimate_host
from sim.sidewalk.topdown import TopDown

TOPDOWN_SIZE = 240     # [px] the sidewalk's top-down view (14 m across)


def finite(x) -> float | None:
    """A number for JSON: None for NaN and infinities."""
    x = float(x)
    return x if math.isfinite(x) else None


def _label(name: str, unit: str, truth, estimate, scale: float) -> dict:
    return {"name": name, "unit": unit, "truth": finite(truth), "estimate": finite(estimate), "scale": scale}


def _truth(rec: StepRecord) -> Any:
    """The highway's GroundTruth of a step."""
    return rec.obs.truth     # type: ignore[attr-defined]


class HighwayView:
    """The front camera, the top-down view with truth and estimate boxes (perception/highway/overlay.py), the 14
    indicators and lanes_left."""

    note = (f"bars full at {ERROR_SCALE['angle']:g} rad (angle), {ERROR_SCALE['toMarking_M']:g} m (markings), "
            f"{ERROR_SCALE['dist_MM']:g} m (gaps)")

    cameras = ("front",)
    units = {q.name: q.unit for q in HIGHWAY.truth}

    def __init__(self, world, track_ref: str):
        self.world, self.track_ref = world, track_ref

    def capture(self, rec: StepRecord, driver_name: str) -> dict:
        obs: Any = rec.obs      # the highway's Observation (frame, truth)
        est = np.asarray(rec.estimate, dtype=np.float64)
        drawn = None if driver_name == "oracle" or not np.isfinite(est[:13]).all() else est
        return {"frame": obs.frame, "truth": obs.truth, "estimate": drawn, "track": self.world.track}

    def images(self, snap: dict) -> list[tuple[str, np.ndarray]]:
        t, est = snap["truth"], snap["estimate"]
        s, d = float(t.ego[3]), float(t.ego[4])
        host = None
        if est is not None:
            ll = est[len(INDICATORS)]
            host = estimate_host(est[:len(INDICATORS)], t.lanes, t.lane_width,
                                 float(ll) if math.isfinite(ll) else None, hint_d=d)
        top = draw_topdown(t.lanes, t.lane_width, s, d, float(t.indicators[INDEX["angle"]]),
                           car_gaps(snap["track"], s, t.cars), host)
        return [("front", snap["frame"]), ("topdown", top)]

    def labels(self, rec: StepRecord) -> list[dict]:
        r, est = rec.obs.record, rec.estimate
        names = INDICATORS + ("lanes_left",)
        return [_label(n, self.units[n], r[HIGHWAY.index(n)], est[i], ERROR_SCALE.get(n, 1.0))
                for i, n in enumerate(names)]

    def controller(self, driver, supervisor, rec: StepRecord) -> dict:
        out = {}
        chen = getattr(driver, "controller", None)
        if chen is not None:
            out["lane-change state"] = chen.state
            out["lane changes"] = chen.lane_changes_started
        if getattr(driver, "label", None) is not None:
            out["perturbation"] = driver.label
        t = _truth(rec)
        out["lane"] = f"{int(t.lanes_left) + 1} of {int(t.lanes)}"
        out["system"] = "both" if t.in_lane and t.on_marking else "in-lane" if t.in_lane else "on-marking"
        return out

    def columns(self, rec: StepRecord, who: str) -> dict:
        return {"track": self.track_ref, "perturbation": who,
                "cars": _truth(rec).cars.astype(np.float32).tolist()}

    def metrics(self, report: dict) -> dict:
        return {"distance_m": report["distance_m"], "collisions": report["collisions"],
                "off_road_events": report["off_road_events"], "lane_changes": report["lane_changes"],
                "mean_speed_mps": report["mean_speed_mps"], "simulated_time_s": report["simulated_time_s"]}


class SidewalkView:
    """The stereo pair, the top-down view of the surroundings (sim/sidewalk/topdown.py), steering and motor against
    the expert's, and the operation mode of every command."""

    cameras = ("left", "right")
    # an estimate this far from the expert fills its bar: the correction rule's deviation thresholds
    scales = {"steer": CorrectionParams.steer_dev, "motor": CorrectionParams.motor_dev}
    note = f"truth: the expert's command on this frame; bars full at {scales['steer']:g} (steer), " \
           f"{scales['motor']:g} (motor)"

    def __init__(self, world, path_ref: str):
        self.world, self.path_ref = world, path_ref
        self.top = TopDown(world.layout, size=TOPDOWN_SIZE, span=14.0)
        self.expert = SidewalkExpert()
        self._first = [SIDEWALK.estimate_names.index(f"{n}+1") for n in ("steer", "motor")]
        self._x, self._y, self._yaw = (SIDEWALK.index(n) for n in ("x", "y", "yaw"))

    def capture(self, rec: StepRecord, driver_name: str) -> dict:
        lead = self.world.lead
        return {"frames": rec.obs.frames, "record": rec.obs.record, "lead": None if lead is None else lead.state}

    def images(self, snap: dict) -> list[tuple[str, np.ndarray]]:
        r = snap["record"]
        top = self.top.draw(float(r[self._x]), float(r[self._y]), float(r[self._yaw]), snap["lead"])
        left, right = snap["frames"]
        return [("left", left), ("right", right), ("topdown", top)]

    def labels(self, rec: StepRecord) -> list[dict]:
        """Truth: the expert's command on this frame (what a demonstration's label would be); estimate: the driver's
        estimate of its next command (steer+1, motor+1)."""
        expert = self.expert.action(rec.obs.record)
        est = np.asarray(rec.estimate, dtype=np.float64)
        return [_label(n, "0..1", expert[k], est[self._first[k]], self.scales[n])
                for k, n in enumerate(("steer", "motor"))]

    def controller(self, driver, supervisor, rec: StepRecord) -> dict:
        r = SIDEWALK.unpack(rec.obs.record)
        out = {"behavioural mode": MODES[r["behaviour"]], "operation": OPERATIONS[r["operation"]],
               "correcting": r["correcting"]}
        rule = getattr(supervisor, "rule", None)
        if rule is not None and rule.correcting:
            out["correction rule"] = rule.reason
        return out

    def columns(self, rec: StepRecord, who: str) -> dict:
        return {"path": self.path_ref}

    def metrics(self, report: dict) -> dict:
        return {"distance_m": report["distance_m"], "collisions": report["collisions"],
                "off_path_time_s": report["off_path_time_s"], "autonomy_percent": report["autonomy_percent"],
                "corrections": report["corrections"], "mean_speed_mps": report["mean_speed_mps"],
                "simulated_time_s": report["simulated_time_s"]}


# what a scene of each world is chosen by: the option, its default, and where its presets come from
SCENES = {"highway": ("track", "oval"), "sidewalk": ("path", "park")}


def scene(world_name: str, args) -> dict:
    """{"track" or "path": what the options name, "seed": ...} of the scene a world is built from."""
    key, default = SCENES[world_name]
    return {key: getattr(args, key, None) or default, "seed": int(getattr(args, "seed", 0) or 0)}


def presets(world_name: str) -> list[str]:
    if SCENES[world_name][0] == "path":
        from sim.sidewalk.paths import preset_names
    else:
        from sim.track.library import preset_names
    return preset_names()


def label_note(world_name: str) -> str:
    """What the labels panel's truth and bars are, in a line for the page."""
    return {"highway": HighwayView.note, "sidewalk": SidewalkView.note}[world_name]


def view_for(world, args):
    """The view of a world (the studio knows these two) built from `args`."""
    name = world.declaration.name
    ref = scene(name, args)[SCENES[name][0]]
    if name == "highway":
        return HighwayView(world, ref)
    if name == "sidewalk":
        return SidewalkView(world, ref)
    raise KeyError(name)
