"""The sidewalk world's configuration and its stereo rig's: every option with its default, unit and range
(core/settings.py), light to import (the command line reads it for --help)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from core.conditions import CONDITIONS, SEEDED
from core.settings import MAX_SEED, setting
from core.worlds.sidewalk import MODES, OPERATIONS, RULES
from sim.camera import CameraConfig
from sim.sidewalk.errors import PathError

BASELINE = 0.12           # [m] between the two cameras' centres (ZED: 120 mm)
EYE_HEIGHT = 0.24         # [m] above the ground
EYE_FORWARD = 0.10        # [m] ahead of the car body's centre
PITCH_DEG = -5.0          # [deg] looking down
FOV_DEG = 56.0            # [deg] vertical field of view
SIZE = (188, 336)         # (rows, columns) per camera
CULL = 60.0               # [m] nothing farther is drawn (a 0.3 m object there is under 1 px wide)




@dataclass(frozen=True)
class StereoConfig:
    width: int = setting(SIZE[1], "frame width of each camera", unit="px", low=16, high=4096)
    height: int = setting(SIZE[0], "frame height of each camera", unit="px", low=16, high=4096)
    fov_deg: float = setting(FOV_DEG, "vertical field of view", unit="deg", low=10.0, high=150.0, flag="--fov")
    baseline: float = BASELINE

    def camera(self, side: str) -> CameraConfig:
        """The left or right camera (or the rig's centre, between them)."""
        offset = {"left": self.baseline / 2, "right": -self.baseline / 2, "centre": 0.0}[side]
        return CameraConfig(width=self.width, height=self.height, fov_deg=self.fov_deg, eye_height=EYE_HEIGHT,
                            eye_forward=EYE_FORWARD, pitch_deg=PITCH_DEG, near=0.05, far=200.0,
                            cull_distance=CULL, eye_left=offset)

    @property
    def focal_px(self) -> float:
        """Focal length [px] (square pixels)."""
        return self.height / 2 / math.tan(math.radians(self.fov_deg) / 2)

    @property
    def hfov_deg(self) -> float:
        return math.degrees(self.camera("left").hfov)

    def disparity(self, depth: float) -> float:
        """[px] of a point `depth` metres along the optical axis."""
        return self.focal_px * self.baseline / depth

    def describe(self) -> dict:
        return {"width": self.width, "height": self.height, "baseline_m": self.baseline,
                "focal_px": round(self.focal_px, 3), "vfov_deg": self.fov_deg, "hfov_deg": round(self.hfov_deg, 3),
                "eye_height_m": EYE_HEIGHT, "eye_forward_m": EYE_FORWARD, "pitch_deg": PITCH_DEG}


DEFAULT_DENSITY = 4.0   # obstacles per 100 m
MAX_DENSITY = 12.0


def obstacles_value(text) -> object:
    """The obstacles of a text: a density (obstacles per 100 m), 'none', or an obstacle file (read and checked when
    the world is built)."""
    if str(text).lower() == "none":
        return 0.0
    try:
        v = float(text)
    except ValueError:
        return str(text)
    if not math.isfinite(v) or not 0.0 <= v <= MAX_DENSITY:
        raise PathError(f"--obstacles must be a density from 0 to {MAX_DENSITY:g} per 100 m, 'none' or an obstacle "
                        f"file, got {text!r}")
    return v


@dataclass
class SidewalkConfig:
    """The sidewalk world's configuration: every option with its default, unit and range (core/settings.py)."""

    # a preset name, a path file, "procedural:SEED", a JSON object or a SidewalkPath
    path: object = setting("park", "path preset (park, sidewalk, forest), path file or procedural:SEED")
    path_width: float | None = setting(None, "path width (default: the path's)", unit="m", low=1.5, high=3.0)
    # looks, borders, trees, obstacle placement, start, lead car
    seed: int = setting(0, "seed of the path's looks, obstacles and start", low=0, high=MAX_SEED)
    mode: str = setting("direct", "behavioural mode", choices=MODES)
    # obstacles per 100 m, a list of layout.Obstacle, or an obstacle file
    obstacles: object = setting(DEFAULT_DENSITY, "obstacles per 100 m, 'none', or an obstacle file",
                                parse=obstacles_value)
    stereo: StereoConfig = field(default_factory=StereoConfig)
    render: bool = True
    start_s: float | None = None       # [m] where the car starts (default: drawn from the seed)
    start_speed: float = 0.0           # [m/s]
    # how the world side applies the driver's commands (drivestudio/worlds/sidewalk/drivers.py Supervisor); None:
    # expert for the world's expert, correctional for any other driver
    operation: str | None = setting(None, "operation mode (default: expert for the expert, correctional otherwise)",
                                    choices=OPERATIONS)
    rule: str = setting("safety", "the correction rule of correctional operation: safety (take over for leaving "
                        "the path, an imminent collision, a stalled car) or strict (also for deviating from the "
                        "expert)", choices=RULES)
    condition: str = setting(SEEDED, "the named condition the frames are drawn in (docs/conditions.md; seeded: the "
                             "seed's own time of day, as always)", choices=CONDITIONS, several=True)
