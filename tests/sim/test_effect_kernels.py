"""The conditions' effects as one compiled call (sim/render/light_kernels.py draw): one compilation serves every
condition of both worlds (pytest's workers load it from numba's cache, compiled once by tests/conftest.py), and its
cached code is dropped when either kernel file changes (numba checks a function's own file only)."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from core.conditions import CONDITIONS
from sim.highway.conditions import draw_condition
from sim.highway.renderer import Renderer
from sim.render import light_kernels
from sim.render.effect_kernels import STEP, falloff
from sim.render.light_kernels import KERNELS, draw, drop_stale_draw
from sim.sidewalk.config import SidewalkConfig, StereoConfig
from sim.sidewalk.world import SidewalkWorld
from sim.track import load_track
from tests.sim.test_conditions import LIT_SEED, frame, one_car

SOURCE = Path(light_kernels.__file__).parent


def test_one_compilation_draws_every_condition_of_both_worlds():
    for name in CONDITIONS[1:]:
        frame(name, mirror=True)
        frame(name, seed=1)
        with SidewalkWorld(SidewalkConfig(path="park", seed=0, condition=name, obstacles=0.0,
                                          stereo=StereoConfig(width=84, height=47))) as world:
            world.observe()
    assert len(draw.signatures) == 1, draw.signatures


def test_draws_cached_code_goes_when_either_kernel_file_changes(tmp_path):
    for f in KERNELS:
        shutil.copy(SOURCE / f, tmp_path / f)
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    compiled = cache / "light_kernels.draw-1.py311.nbi"
    own = cache / "effect_kernels.ground-1.py311.nbi"   # numba drops it itself when its file changes
    for f in (compiled, own):
        f.write_text("")
    drop_stale_draw(tmp_path)
    assert not compiled.exists() and own.exists()
    compiled.write_text("")
    drop_stale_draw(tmp_path)   # nothing changed since
    assert compiled.exists()
    (tmp_path / "effect_kernels.py").write_text((tmp_path / "effect_kernels.py").read_text() + "\n# changed\n")
    drop_stale_draw(tmp_path)
    assert not compiled.exists() and own.exists()


def test_the_headlights_falloff_computed_is_its_tables_value():
    """The objects' headlights compute the falloff (a loop the compiler vectorises) that Effects' table holds."""
    rng = np.random.default_rng(0)
    d = np.arange(int(400 * STEP) + 1) / STEP
    at = np.r_[rng.uniform(0.0, 420.0, 2000), d, np.nextafter(d, -1.0), 1e6].astype(np.float32)
    at = np.maximum(at, 0.0)
    for reach in (1e-3, 7.3, 35.0, 61.37, 150.0):
        table = (1.0 / (1.0 + (d / reach) ** 2)).astype(np.float32)
        want = table[np.minimum((at.astype(np.float64) * STEP).astype(np.uint64), len(table) - 1)]
        got = np.array([falloff(a, float(len(table) - 1), reach) for a in at], dtype=np.float32)
        assert np.array_equal(got, want), reach


# the objects' tables (sim/render/effects.py Effects._groups: objects_) that hold a shortcut, and their general case
ROW_VIEW, NEAR, ONE_VIEW = 10, 12, 14


def _without_shortcuts(objects: tuple) -> tuple:
    """The tables drawn the long way: every row as one of several views (its pixels shaded one by one at night),
    every distance mirrored (no row's range tested first), the view read at each reflection."""
    general = list(objects)
    general[ROW_VIEW] = np.full_like(objects[ROW_VIEW], -1)
    general[NEAR] = np.stack([np.zeros_like(objects[NEAR][..., 0]), np.full_like(objects[NEAR][..., 1], np.inf)], -1)
    general[ONE_VIEW] = False
    return tuple(general)


def test_the_objects_shortcuts_draw_the_long_ways_pixels():
    """A row of one view is shaded a whole row at a time, the distances outside which a row's pixels cannot be
    mirrored are tested first, and a frame of one view does not read the view at each reflection: drawn without
    these shortcuts the pixels are the same, at night on a lit road (the lamps' light on the cars) and in rain."""
    track = load_track("oval", lanes=2)
    d = float(track.lane_centres[1])
    for name in ("night", "rain"):
        r = Renderer(track, LIT_SEED, None, "numba", condition=draw_condition(name, LIT_SEED))
        try:
            effects = r.effects.effects
            for s in (25.0, 140.0):
                x, y, yaw = track.pose(s, d)
                cars = one_car(track, s + 9.0, d)
                frames = []
                for general in (False, True):
                    if general:
                        tables = list(effects._tables)
                        assert tables[4][NEAR].shape[-1] == 2 and tables[4][ONE_VIEW] is True, name
                        tables[4] = _without_shortcuts(tables[4])
                        effects._tables = tuple(tables)
                    effects._frames = 0
                    frames.append(r.render(x, y, yaw, cars))
                assert np.array_equal(frames[0], frames[1]), (name, s)
                effects._tables = effects._groups()
        finally:
            r.close()
