"""drive --record on the highway: every step's box overlay (truth beside the driver's estimate) into an mp4."""
from __future__ import annotations

from typing import TYPE_CHECKING, cast

import numpy as np

from core.worlds.highway import INDICATORS, REAR
from drivestudio.loop import StepRecord
from drivestudio.outputs import VideoWriter
from drivestudio.worlds.highway.drivers import ESTIMATE_INDEX, ORACLES
from drivestudio.worlds.highway.overlays import overlay_observation

if TYPE_CHECKING:
    from sim.highway.world import Observation, World


class OverlayRecorder:
    """drive --record: every step's overlay (truth and the driver's estimate) into an mp4."""

    def __init__(self, path, world: World, label: str):
        self.writer = VideoWriter(path) if path else None
        self.world, self.label = world, label

    def __call__(self, rec: StepRecord) -> None:
        if self.writer is not None:
            obs = cast("Observation", rec.obs)   # the highway plugin records only its own world's runs
            t = obs.truth
            title = f"t {rec.obs.t:5.1f} s  {self.world.track.name}, {t.lanes} lanes, {t.speed:4.1f} m/s"
            exact = self.label in ORACLES   # an oracle's estimate is the truth: nothing to draw beside it
            estimate = None if exact else np.asarray(rec.estimate)[:len(INDICATORS)]
            ll = None if exact else rec.estimate[ESTIMATE_INDEX["lanes_left"]]
            rear = None if exact else np.asarray(rec.estimate)[[ESTIMATE_INDEX[n] for n in REAR]]
            self.writer.write(overlay_observation(obs, estimate, self.world.track, title,
                                                  None if ll is None or not np.isfinite(ll) else float(ll),
                                                  label=self.label, rear=rear))

    def close(self, ok: bool) -> None:
        if self.writer is not None:
            (self.writer.close if ok else self.writer.abort)()
            if ok:
                print(f"recorded {self.writer.frames} overlays to {self.writer.path}")
