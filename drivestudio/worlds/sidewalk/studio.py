"""The sidewalk in the studio (drivestudio/studio/kit.py): the stereo pair, the top-down view of the surroundings
(sim/sidewalk/topdown.py), steering and motor against the expert's, and a person's RC transmitter."""
from __future__ import annotations

import numpy as np

from controller.sidewalk import SidewalkExpert
from controller.sidewalk.correction import CorrectionParams
from core.worlds.sidewalk import MODES, OPERATIONS, SIDEWALK, STEER_LOCK_RAD, TOP_SPEED, WHEELBASE
from drivestudio.loop import StepRecord
from drivestudio.studio.kit import HumanMap, StudioKit, finite, label_row
from sim.sidewalk.paths import preset_names
from sim.sidewalk.topdown import TopDown

TOPDOWN_SIZE = 240     # [px] the sidewalk's top-down view (14 m across)


class SidewalkView:
    """The stereo pair, the top-down view of the surroundings (sim/sidewalk/topdown.py), steering and motor against
    the expert's, and the operation mode of every command."""

    cameras: tuple[str, ...] = ("left", "right")
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
        self._speed, self._off_path = SIDEWALK.index("speed"), SIDEWALK.index("off_path")

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
        return [label_row(n, "0..1", expert[k], est[self._first[k]], self.scales[n])
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
        return {"path": self.path_ref, "condition": self.world.condition}

    def metrics(self, report: dict) -> dict:
        return {"distance_m": report["distance_m"], "collisions": report["collisions"],
                "off_path_time_s": report["off_path_time_s"], "autonomy_percent": report["autonomy_percent"],
                "corrections": report["corrections"], "mean_speed_mps": report["mean_speed_mps"]}

    def live(self, rec: StepRecord) -> dict:
        r = rec.obs.record
        return {"speed": finite(r[self._speed]), "off_road": bool(r[self._off_path])}



FORWARD = 4.5 / TOP_SPEED   # full throttle asks 4.5 m/s (the experts drive 0.9-4.5)
REVERSE = 3.0 / TOP_SPEED   # full brake asks 3 m/s backwards, as an RC car's brake turns to reverse

# Full steering turns the car at most 4 m/s^2, built at most 10 m/s^3 by a held key: at an RC car's speeds the key's
# own 0.4 s to full steering, as nimble as a transmitter's stick. steer 0.5 straight, 1 full right; motor 0.5 stop.
HUMAN = HumanMap(4.0, 10.0, WHEELBASE, STEER_LOCK_RAD,
                 lambda s, t, b: np.array([0.5 + 0.5 * s, 0.5 + 0.5 * (FORWARD * t - REVERSE * b)], dtype=np.float64))

KIT = StudioKit("path", "park", preset_names, SidewalkView, SidewalkView.note, HUMAN)
