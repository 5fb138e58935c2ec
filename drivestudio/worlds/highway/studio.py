"""The highway in the studio (drivestudio/studio/kit.py): the front camera, the top-down view with truth and estimate
boxes (perception/highway/overlay.py), the 14 indicators and lanes_left, and a person's pedals."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from core.worlds.highway import HIGHWAY, INDEX, INDICATORS, STEER_LOCK_RAD
from drivestudio.loop import StepRecord
from drivestudio.studio.kit import HumanMap, StudioKit, finite, label_row
from drivestudio.worlds.highway.overlays import car_gaps
from perception.highway.overlay import ERROR_SCALE, draw_topdown, estimate_host
from sim.highway.vehicle import VehicleParams
from sim.track.library import preset_names


def _truth(rec: StepRecord) -> Any:
    """The highway's GroundTruth of a step."""
    return rec.obs.truth     # type: ignore[attr-defined]


class HighwayView:
    """The front camera, the top-down view with truth and estimate boxes (perception/highway/overlay.py), the 14
    indicators and lanes_left."""

    note = (f"bars full at {ERROR_SCALE['angle']:g} rad (angle), {ERROR_SCALE['toMarking_M']:g} m (markings), "
            f"{ERROR_SCALE['dist_MM']:g} m (gaps)")

    cameras: tuple[str, ...] = ("front",)
    units = {q.name: q.unit for q in HIGHWAY.truth}
    _speed, _off_road = HIGHWAY.index("speed"), HIGHWAY.index("off_road")

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
        return [label_row(n, self.units[n], r[HIGHWAY.index(n)], est[i], ERROR_SCALE.get(n, 1.0))
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
        report = self.world.scenario_report()
        if report is not None:   # a scripted scenario (docs/scenarios.md): what it did so far, and how it goes
            out["scenario"] = f"{report['scenario']}: {len(report['events'])} of {len(self.world.script.events)} events"
            out["verdict"] = "passing so far" if report["passed"] else "failed: " + "; ".join(report["failed"])
        return out

    def columns(self, rec: StepRecord, who: str) -> dict:
        return {"track": self.track_ref, "perturbation": who,
                "cars": _truth(rec).cars.astype(np.float32).tolist(), "condition": self.world.condition}

    def metrics(self, report: dict) -> dict:
        return {"distance_m": report["distance_m"], "collisions": report["collisions"],
                "off_road_events": report["off_road_events"], "lane_changes": report["lane_changes"],
                "mean_speed_mps": report["mean_speed_mps"]}

    def live(self, rec: StepRecord) -> dict:
        r = rec.obs.record
        return {"speed": finite(r[self._speed]), "off_road": bool(r[self._off_road])}



# Full steering turns the car at most 6 m/s^2 (two thirds of its grip), built at most 3 m/s^3 by a held key: at
# speed, 2 s to full steering, and a 0.6 s tap leaves the car drifting sideways at about 0.6 m/s, a sixth of a lane
# a second, where a person has time to correct it. steer + left, accel and brake pedals.
HUMAN = HumanMap(6.0, 3.0, VehicleParams().wheelbase, STEER_LOCK_RAD,
                 lambda s, t, b: np.array([-s, t, b], dtype=np.float64))

KIT = StudioKit("track", "oval", preset_names, HighwayView, HighwayView.note, HUMAN)
