"""drive --record on the sidewalk: both cameras and a top-down view per step, with a line of what is happening."""
from __future__ import annotations

import cv2
import numpy as np

from core.worlds.sidewalk import MODES, OPERATIONS, SIDEWALK
from drivestudio.loop import StepRecord
from drivestudio.outputs import VideoWriter
from sim.sidewalk.topdown import TopDown


class Recorder:
    """drive --record: per step, both cameras and a top-down view, with a line of what is happening (30 fps)."""

    def __init__(self, path, world, label: str):
        self.writer = VideoWriter(path, fps=round(1 / world.dt))
        self.world, self.label = world, label
        h = world.declaration.camera("left").height
        self.top = TopDown(world.layout, size=h + (h % 2), span=14.0)

    def __call__(self, rec: StepRecord) -> None:
        obs = rec.obs
        left, right = obs.frames
        if left is None:
            return
        r = SIDEWALK.unpack(obs.record)
        lead = self.world.lead.state if self.world.lead is not None else None
        top = self.top.draw(r["x"], r["y"], r["yaw"], lead)
        a = np.asarray(rec.action, dtype=np.float64)
        text = (f"t {obs.t:5.1f} s  {MODES[r['behaviour']]}  {OPERATIONS[r['operation']]}  {r['speed']:4.2f} m/s  "
                f"steer {a[0]:.2f}  motor {a[1]:.2f}  {self.label}")
        self.writer.write(compose(left, right, top, text, r["collision"], r["correcting"]))

    def close(self, ok: bool) -> None:
        (self.writer.close if ok else self.writer.abort)()
        if ok:
            print(f"recorded {self.writer.frames} frames to {self.writer.path}")


def compose(left: np.ndarray, right: np.ndarray, top: np.ndarray | None, text: str, alarm: bool = False,
            correcting: bool = False) -> np.ndarray:
    """[left | right | top-down] over a status line (RGB)."""
    h = left.shape[0]
    parts = [left, right] + ([top[:h, :h]] if top is not None else [])
    row = np.concatenate(parts, axis=1)
    bar = np.full((24, row.shape[1], 3), (30, 30, 30), np.uint8)
    if correcting:
        bar[:] = (150, 110, 0)
    if alarm:
        bar[:] = (160, 30, 30)
    cv2.putText(bar, text, (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (235, 235, 235), 1, cv2.LINE_AA)
    out = np.concatenate([row, bar], axis=0)
    if out.shape[1] % 2:
        out = np.concatenate([out, out[:, -1:]], axis=1)
    return out
