"""The highway world's configuration: every option with its default, unit and range (core/settings.py), light to
import (the command line reads it for --help)."""
from __future__ import annotations

from dataclasses import dataclass, field

from core.conditions import CONDITIONS, SEEDED
from core.settings import MAX_SEED, setting
from core.worlds.highway import MAX_LANES
from sim.camera import DEFAULT_RENDERER, RENDERERS, CameraConfig
from sim.highway.errors import RendererError
from sim.highway.vehicle import VehicleParams
from sim.mirror import inset_name
from sim.render.available import renderer_problem

MAX_CARS = 300   # AI cars SUMO drives at most


@dataclass
class WorldConfig:
    """The highway world's configuration: every option with its default, unit and range (core/settings.py)."""

    # a preset name, a track file, a track object or "procedural:SEED"
    track: object = setting("oval", "track preset, track file or procedural:SEED")
    lanes: int | None = setting(None, "lane count (default: the track's)", low=1, high=MAX_LANES)
    lane_width: float | None = None
    cars: int = setting(12, "AI cars driven by SUMO (scenarios bring their own)", low=0, high=MAX_CARS)
    dt: float = 0.1                 # [s] one world step (10 Hz, as DeepDriving's loop)
    seed: int = setting(0, "seed of the scene and the traffic", low=0, high=MAX_SEED)
    render: bool = True
    renderer: str = setting(DEFAULT_RENDERER, "how frames are drawn: the compiled rasteriser (numba), PyBullet's "
                            "TinyRenderer (tiny) or EGL plugin (egl), OpenGL (gl); docs/rendering.md",
                            choices=RENDERERS)
    camera: CameraConfig = field(default_factory=CameraConfig)
    mirror: bool = setting(False, "paste a rear-view mirror into the top of the frame (docs/rendering.md)")
    side_views: bool = setting(False, "with the mirror (implied): the views out of both side windows below it, where "
                               "a car level with the host shows (docs/rendering.md)")
    condition: str = setting(SEEDED, "the named condition the frames are drawn in (docs/conditions.md; seeded: the "
                             "seed's own sunny or overcast look, as always)", choices=CONDITIONS, several=True)
    vehicle: VehicleParams = field(default_factory=VehicleParams)
    # scenarios set their own speeds
    start_speed: float = setting(15.0, "host car's speed at the start", unit="m/s", low=0.0, high=60.0)
    start_lane: int | None = None   # host car's lane after reset, 0 = leftmost (None: drawn from the seed)
    sumo: str = "auto"              # "libsumo", "traci" or "auto": libsumo while free (sim/highway/sumo_connection.py)
    scenario: str | None = setting(None, "a scripted scenario file: its route, cars and events replace track, lanes, "
                                   "cars, seed and the start (docs/scenarios.md)")

    def __post_init__(self) -> None:
        problem = renderer_problem(self.renderer)   # before any work: a renderer this machine lacks is refused here
        if problem is not None:
            raise RendererError(f"renderer {self.renderer}: {problem}")

    @property
    def inset(self) -> str:
        """What the frames hold besides the scene (core/declaration.py Camera.inset)."""
        return inset_name(self.mirror, self.side_views)
