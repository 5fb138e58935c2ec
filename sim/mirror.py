"""A rear-view mirror composited into the top of the front camera's frame (docs/rendering.md#the-rear-view-mirror).

DeepDriving's indicators see only cars ahead, and a front camera cannot show what is beside or behind: the
extended labels (dist_LB, dist_RB and their closing speeds) are unobservable from it. A driver looks in the
mirror. This one is a second, wide camera on the host car's roof looking backwards; its image is flipped left to
right, as a mirror shows it (a car in the lane to the left appears on the left), and pasted into a strip at the
top centre of the frame, where the front view holds only sky. The frame keeps its size, so every model family,
dataset and bridge reads it unchanged; the camera's declaration names the inset (`Camera.inset = "mirror"`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.camera import CameraConfig

WIDTH_SHARE = 0.8      # of the frame's width: 224 px of 280
HEIGHT_SHARE = 0.25    # of the frame's height: 52 px of 210
TOP_SHARE = 0.02       # gap above it: 4 px of 210; the front view's horizon lies near row 99, far below
HFOV_DEG = 90.0        # a car in the next lane shows from a gap of about 2 m; wider would shrink the far ones
EYE_HEIGHT = 1.5       # [m] on the roof, above the driver's eye, to see over the car just behind
PITCH_DEG = -4.0       # looking slightly down: the road behind fills the lower part
BORDER = 2             # [px] the mirror's dark frame
BORDER_RGB = (24, 24, 24)


@dataclass(frozen=True)
class RearMirror:
    """The mirror for a front frame of `frame_height` x `frame_width` pixels."""

    frame_height: int
    frame_width: int

    @property
    def rect(self) -> tuple[int, int, int, int]:
        """(top, left, height, width) of the mirror in the frame [px], border included."""
        h = max(8, round(self.frame_height * HEIGHT_SHARE))
        w = max(16, round(self.frame_width * WIDTH_SHARE))
        return round(self.frame_height * TOP_SHARE), (self.frame_width - w) // 2, h, w

    @property
    def camera(self) -> CameraConfig:
        """The rear camera (drawn with the host's yaw + pi) for the mirror's glass, inside the border."""
        _, _, h, w = self.rect
        gh, gw = h - 2 * BORDER, w - 2 * BORDER
        vfov = 2 * math.degrees(math.atan(math.tan(math.radians(HFOV_DEG) / 2) * gh / gw))
        return CameraConfig(width=gw, height=gh, fov_deg=vfov, eye_height=EYE_HEIGHT, eye_forward=0.0,
                            pitch_deg=PITCH_DEG, far=150.0, cull_distance=120.0)

    def composite(self, frame: np.ndarray, rear: np.ndarray) -> np.ndarray:
        """Paste the rear camera's image `rear`, flipped left to right, into `frame` (in place); returns frame."""
        top, left, h, w = self.rect
        frame[top:top + h, left:left + w] = BORDER_RGB
        frame[top + BORDER:top + h - BORDER, left + BORDER:left + w - BORDER] = rear[:, ::-1]
        return frame
