"""A view of the scene drawn into a rectangle of the frame: where, from which camera, and what is in it."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.camera import CameraConfig

# where each renderer puts a point, in pixels of the camera's image (right, down) from where OpenGL puts it: the
# painter (sim/ground_painter.py) puts pixel centres where OpenGL does; TinyRenderer samples a pixel at its corner
GROUND_SHIFT_PX = (0.0, 0.0)
OBJECT_SHIFT_PX = (0.5, -0.5)


@dataclass
class View:
    rect: tuple[int, int, int, int]          # (top, left, height, width) of the view in the frame [px]
    matrix: np.ndarray                       # (4, 4) world to OpenGL clip space, rows of the frame top down
    ground_shift: tuple[float, float]        # NDC
    object_shift: tuple[float, float]        # NDC
    clockwise: bool                          # front faces wind clockwise in the frame (one flip) or not (two)
    groups: np.ndarray                       # (n_groups,) bool: the groups (chunks) in view
    cars: list[np.ndarray]                   # per model: (k, 7) instances in view (x, y, cos, sin, paint 0-255)
    keep: tuple[int, int, int, int] | None = None   # a rectangle later views leave as this one drew it
    clip: tuple[float, float] = (0.3, 300.0)         # [m] the camera's near and far planes (its depth's scale)


def camera_view(camera: CameraConfig, x: float, y: float, yaw: float, rect: tuple[int, int, int, int],
                groups: np.ndarray, cars: list[np.ndarray], mirrored: bool = False,
                keep: tuple[int, int, int, int] | None = None) -> View:
    """The view of `camera` on a car at (x, y) [m] with yaw [rad] into `rect` (its size is the camera's), flipped
    left to right when `mirrored`. The frame's rows go top down in OpenGL's rows, so every view is flipped upside
    down as well; a flip turns a face's winding."""
    proj = np.array(camera.projection_matrix()).reshape(4, 4).T
    view = np.array(camera.view_matrix(x, y, yaw)).reshape(4, 4).T
    fx = -1.0 if mirrored else 1.0
    matrix = np.diag([fx, -1.0, 1.0, 1.0]) @ proj @ view
    w, h = camera.width, camera.height

    def shift(px):
        return (fx * 2.0 * px[0] / w, 2.0 * px[1] / h)

    return View(rect, matrix, shift(GROUND_SHIFT_PX), shift(OBJECT_SHIFT_PX), not mirrored, groups, cars, keep,
                (camera.near, camera.far))
