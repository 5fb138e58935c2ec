"""Renderer numba's kernels, compiled ahead of the first frame."""
from __future__ import annotations

import numpy as np

from sim.highway.conditions import draw_condition
from sim.highway.renderer import Renderer
from sim.highway.traffic import CarStates
from sim.track import load_track


def compile_numba_kernels() -> None:
    """Compile (or load from numba's cache) every kernel of renderer numba by drawing one frame with the mirror and the
    side views: a process that is about to start others that render compiles once for them all."""
    track = load_track("oval", lanes=2)
    Renderer(track, 0, renderer="numba", mirror=True, sides=True).render(0.0, 0.0, 0.0, CarStates.empty())
    # and the named conditions' effects (sim/render/effects.py), every kernel of them: seed 0's road has street lamps
    x, y, yaw = track.pose(0.0, 0.0)
    ahead = track.pose(20.0, 0.0)
    one = np.ones(1)
    car = CarStates(one * ahead[0], one * ahead[1], one * ahead[2], one * 20.0, 0 * one, one * 4.5, one * 1.8,
                    np.zeros(1, int), np.zeros(1, int), one * 10.0)
    for name in ("night", "rain", "low_sun"):
        Renderer(track, 0, renderer="numba", mirror=True, sides=True, condition=draw_condition(name, 0)).render(
            x, y, yaw, car)
