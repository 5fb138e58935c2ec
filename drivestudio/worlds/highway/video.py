"""drive --record on the highway: every step's box overlay (truth beside the driver's estimate) into an mp4."""
from __future__ import annotations

from typing import TYPE_CHECKING, cast

import numpy as np

from core.worlds.highway import INDICATORS
from drivestudio.loop import StepRecord
from drivestudio.outputs import VideoWriter
from drivestudio.worlds.highway.drivers import ESTIMATE_INDEX
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
            estimate = None if self.label == "oracle" else np.asarray(rec.estimate)[:len(INDICATORS)]
            ll = None if self.label == "oracle" else rec.estimate[ESTIMATE_INDEX["lanes_left"]]
            self.writer.write(overlay_observation(obs, estimate, self.world.track, title,
                                                  None if ll is None or not np.isfinite(ll) else float(ll),
                                                  label=self.label))

    def close(self, ok: bool) -> None:
        if self.writer is not None:
            (self.writer.close if ok else self.writer.abort)()
            if ok:
                print(f"recorded {self.writer.frames} overlays to {self.writer.path}")
