"""The conditions' effects as one compiled call (sim/render/light_kernels.py draw): one compilation serves every
condition of both worlds (pytest's workers load it from numba's cache, compiled once by tests/conftest.py), and its
cached code is dropped when either kernel file changes (numba checks a function's own file only)."""
from __future__ import annotations

import shutil
from pathlib import Path

from core.conditions import CONDITIONS
from sim.render import light_kernels
from sim.render.light_kernels import KERNELS, draw, drop_stale_draw
from sim.sidewalk.config import SidewalkConfig, StereoConfig
from sim.sidewalk.world import SidewalkWorld
from tests.sim.test_conditions import frame

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
