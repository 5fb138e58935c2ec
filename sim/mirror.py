"""A rear-view mirror composited into the top of the front camera's frame (docs/rendering.md#the-rear-view-mirror).

DeepDriving's indicators see only cars ahead, and a front camera cannot show what is beside or behind: the
extended labels (dist_LB, dist_RB and their closing speeds) are unobservable from it. A driver looks in the
mirror. This one is a second, wide camera on the host car's roof looking backwards; its image is flipped left to
right, as a mirror shows it (a car in the lane to the left appears on the left), and pasted into a strip at the
top centre of the frame, where the front view holds only sky. The frame keeps its size, so every model family,
dataset and bridge reads it unchanged; the camera's declaration names the inset (`Camera.inset = "mirror"`).

A car level with the host is in neither the front view nor the mirror: the blind spot. `SideViews` adds what a
driver's glance over the shoulder shows: two more cameras on the roof looking left and right out of the side
windows, pasted below the mirror at the frame's outer edges (inset "mirror+sides").
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
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

SIDE_TOP_SHARE = 0.276      # rows 58-89 of 210: below the mirror, above the front view's horizon (row ~99)
SIDE_HEIGHT_SHARE = 0.152   # 32 px of 210
SIDE_WIDTH_SHARE = 0.357    # 100 px of 280 each, at the outer edges: the middle, where the lane ahead lies, stays
SIDE_MARGIN_SHARE = 0.015   # 4 px from the frame's edge
SIDE_HFOV_DEG = 90.0        # 45-135 degrees from ahead: the front view ends at 38, the mirror begins at 135
SIDE_PITCH_DEG = -12.0      # looking down: a car in the next lane, 2-5 m away, fills the window's height

INSET_FLAGS = {"": (False, False), "mirror": (True, False), "mirror+sides": (True, True)}  # inset: (mirror, sides)


def glass(rect: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """The rectangle (top, left, height, width) inside an inset's border: where its camera's image goes."""
    top, left, h, w = rect
    return top + BORDER, left + BORDER, h - 2 * BORDER, w - 2 * BORDER


def inset_name(mirror: bool, side_views: bool = False) -> str:
    """The camera's inset (core/declaration.py) for a world with the mirror and the side views; sides need the
    mirror (they see the blind spot between it and the front view)."""
    return "mirror+sides" if side_views else ("mirror" if mirror else "")


def inset_options(inset: str) -> dict:
    """The world options (generate's, WorldConfig's) that render `inset`, those switched on only."""
    return {k: True for k, on in zip(("mirror", "side_views"), INSET_FLAGS[inset]) if on}


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
        # flipped by OpenCV: numpy's strided copy of rear[:, ::-1] takes over ten times as long
        frame[top + BORDER:top + h - BORDER, left + BORDER:left + w - BORDER] = cv2.flip(rear, 1)
        return frame


@dataclass(frozen=True)
class SideViews:
    """The views out of the left and right side windows for a front frame of `frame_height` x `frame_width` pixels:
    the left one at the frame's left edge, the right one at its right, each a camera's image as it is (not flipped:
    a window, not a mirror; the left view shows ahead on its right, the right view ahead on its left)."""

    frame_height: int
    frame_width: int

    @property
    def rects(self) -> tuple[tuple[int, int, int, int], tuple[int, int, int, int]]:
        """(top, left, height, width) of the left and the right view in the frame [px], border included."""
        top, h = round(self.frame_height * SIDE_TOP_SHARE), max(8, round(self.frame_height * SIDE_HEIGHT_SHARE))
        w, margin = max(16, round(self.frame_width * SIDE_WIDTH_SHARE)), round(self.frame_width * SIDE_MARGIN_SHARE)
        return (top, margin, h, w), (top, self.frame_width - margin - w, h, w)

    @property
    def camera(self) -> CameraConfig:
        """The side cameras (drawn with the host's yaw +- pi/2) for a view's glass, inside the border."""
        _, _, h, w = self.rects[0]
        gh, gw = h - 2 * BORDER, w - 2 * BORDER
        vfov = 2 * math.degrees(math.atan(math.tan(math.radians(SIDE_HFOV_DEG) / 2) * gh / gw))
        return CameraConfig(width=gw, height=gh, fov_deg=vfov, eye_height=EYE_HEIGHT, eye_forward=0.0,
                            pitch_deg=SIDE_PITCH_DEG, far=150.0, cull_distance=120.0)

    def composite(self, frame: np.ndarray, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        """Paste the left and right cameras' images into `frame` (in place); returns frame."""
        for (top, x0, h, w), image in zip(self.rects, (left, right)):
            frame[top:top + h, x0:x0 + w] = BORDER_RGB
            frame[top + BORDER:top + h - BORDER, x0 + BORDER:x0 + w - BORDER] = image
        return frame
