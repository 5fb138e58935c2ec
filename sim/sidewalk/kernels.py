"""The stereo renderer's numba kernels (sim/render/raster_stereo.py), compiled ahead of the first pair."""
from __future__ import annotations

from sim.sidewalk.conditions import draw_condition
from sim.sidewalk.config import StereoConfig
from sim.sidewalk.layout import build_layout
from sim.sidewalk.lead import LeadCar
from sim.sidewalk.paths import load_path
from sim.sidewalk.stereo import StereoRenderer


def compile_stereo_kernels() -> None:
    """Compile (or load from numba's cache) every kernel of the stereo renderer by drawing a small pair with the lead
    car, without depth (the seeded look) and with it (fog): a process that is about to start others that render
    compiles once for them all."""
    path = load_path("park")
    layout = build_layout(path, 0, 4.0, None)
    rig = StereoConfig(width=84, height=47)
    x, y, yaw = (float(v) for v in path.track.pose(layout.start_s, 0.0))
    lead = LeadCar(layout, 0, layout.start_s + 2.0, 0.0).state
    for condition in (None, draw_condition("fog", 0, path.style)):
        StereoRenderer(layout, 0, rig, condition).render(x, y, yaw, lead)
