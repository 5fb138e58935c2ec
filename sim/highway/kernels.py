"""Renderer numba's kernels, compiled ahead of the first frame."""
from __future__ import annotations

from sim.highway.renderer import Renderer
from sim.highway.traffic import CarStates
from sim.track import load_track


def compile_numba_kernels() -> None:
    """Compile (or load from numba's cache) every kernel of renderer numba by drawing one frame with the mirror and the
    side views: a process that is about to start others that render compiles once for them all."""
    Renderer(load_track("oval", lanes=2), 0, renderer="numba", mirror=True, sides=True).render(
        0.0, 0.0, 0.0, CarStates.empty())
