"""The host car's first-person camera: where it sits, what it sees, and the OpenGL matrices for it."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from core.settings import setting
from core.worlds.highway import FRAME

# how frames are drawn (sim/highway/renderer.py): PyBullet's TinyRenderer or EGL plugin, the compiled rasteriser, OpenGL
RENDERERS = ("tiny", "egl", "numba", "gl")
# the compiled rasteriser draws TinyRenderer's frames (docs/rendering.md) about nine times as fast on a CPU
DEFAULT_RENDERER = "numba"

@dataclass(frozen=True)
class CameraConfig:
    width: int = setting(FRAME[1], "frame width", unit="px", low=16, high=4096)   # the highway declaration's camera
    height: int = setting(FRAME[0], "frame height", unit="px", low=16, high=4096)
    fov_deg: float = setting(60.0, "vertical field of view", unit="deg", low=10.0, high=150.0, flag="--fov")
    eye_height: float = 1.2     # [m] driver's eye above the road
    eye_forward: float = 0.3    # [m] ahead of the car's centre
    pitch_deg: float = -2.0     # [deg] negative looks down
    near: float = 0.3           # [m]
    far: float = 300.0          # [m]
    cull_distance: float = 220.0  # [m] nothing farther is drawn
    eye_left: float = 0.0       # [m] to the left of the car's axis: one camera of a stereo pair

    @property
    def aspect(self) -> float:
        return self.width / self.height

    @property
    def hfov(self) -> float:
        """Horizontal field of view [rad]."""
        return 2 * math.atan(math.tan(math.radians(self.fov_deg) / 2) * self.aspect)

    def horizon_row(self) -> float:
        """Image row (0 = top) where a level, infinitely distant ground meets the sky."""
        y_ndc = math.tan(-math.radians(self.pitch_deg)) / math.tan(math.radians(self.fov_deg) / 2)
        return (1 - y_ndc) / 2 * self.height

    def eye(self, x: float, y: float, yaw: float) -> tuple[np.ndarray, np.ndarray]:
        """Eye position and unit viewing direction for a car at (x, y) [m] with yaw [rad]."""
        c, s = math.cos(yaw), math.sin(yaw)
        eye = np.array([x + self.eye_forward * c, y + self.eye_forward * s, self.eye_height])
        if self.eye_left:   # only then: a centred camera's eye stays bit for bit what it was
            eye[:2] += (-self.eye_left * s, self.eye_left * c)
        p = math.radians(self.pitch_deg)
        return eye, np.array([math.cos(p) * c, math.cos(p) * s, math.sin(p)])

    def basis(self, x: float, y: float, yaw: float) -> tuple[np.ndarray, np.ndarray]:
        """Eye position and the camera's (right, up, forward) unit vectors as rows of a 3x3 matrix."""
        eye, f = self.eye(x, y, yaw)
        c, s = math.cos(yaw), math.sin(yaw)
        side = np.array([s, -c, 0.0])  # forward x world-up, for a camera that never rolls
        up = np.array([-f[2] * c, -f[2] * s, f[0] * c + f[1] * s])  # side x forward
        return eye, np.stack([side, up, f])

    def view_matrix(self, x: float, y: float, yaw: float) -> list[float]:
        """Column-major 4x4 view matrix (OpenGL lookAt)."""
        eye, (side, up, f) = self.basis(x, y, yaw)
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = side, up, -f
        m[:3, 3] = -m[:3, :3] @ eye
        return m.T.reshape(-1).tolist()

    def projection_matrix(self) -> list[float]:
        """Column-major 4x4 perspective projection (OpenGL)."""
        f = 1.0 / math.tan(math.radians(self.fov_deg) / 2)
        n, fa = self.near, self.far
        m = np.zeros((4, 4))
        m[0, 0], m[1, 1] = f / self.aspect, f
        m[2, 2], m[2, 3] = (fa + n) / (n - fa), 2 * fa * n / (n - fa)
        m[3, 2] = -1.0
        return m.T.reshape(-1).tolist()
