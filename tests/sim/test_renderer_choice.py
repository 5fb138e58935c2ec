"""Choosing a renderer (docs/rendering.md#the-fast-renderers): the world's `renderer` setting selects it wherever a
world is made (--set renderer=NAME, WorldConfig, the Gymnasium environment's keyword), a renderer this machine lacks
is refused in one line before any work, and a dataset records which renderer drew it."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401  registers the environments
from drivestudio import worlds
from drivestudio.generate import GenerateConfig, generate
from perception.shards import read_manifest
from sim.camera import RENDERERS, CameraConfig
from sim.highway.config import WorldConfig
from sim.highway.errors import RendererError
from sim.render.available import renderer_problem

REPO = Path(__file__).resolve().parents[2]


def test_the_fast_renderers_are_choices_of_the_setting_and_tiny_stays_the_default():
    assert {"tiny", "egl", "numba", "gl"} == set(RENDERERS) and WorldConfig().renderer == "numba"


def test_set_renderer_draws_the_frame_with_it(run_cli, tmp_path):
    r = run_cli("render", "-o", tmp_path / "f.png", "--track", "oval", "--cars", "0", "--set", "renderer=numba",
                "--set", "camera.width=140", "--set", "camera.height=105")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "f.png").stat().st_size > 0


def test_a_renderer_this_machine_lacks_is_refused_in_one_line_before_any_work(run_cli, tmp_path, monkeypatch):
    monkeypatch.setattr("sim.highway.config.renderer_problem", lambda name: "numba cannot be imported (test)"
                        if name == "numba" else None)
    r = run_cli("render", "-o", tmp_path / "f.png", "--track", "oval", "--set", "renderer=numba")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "renderer numba: numba cannot be imported (test)" in r.stderr
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(RendererError, match="renderer numba"):
        WorldConfig(renderer="numba")


def test_gl_without_an_egl_driver_is_refused_in_one_line():
    """A fresh process whose EGL finds no driver: --set renderer=gl exits 2 with one line saying what to install."""
    env = {**os.environ, "__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent.json"}
    r = subprocess.run([sys.executable, "-m", "drivestudio", "render", "-o", "never.png", "--track", "oval",
                        "--set", "renderer=gl"], cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "renderer gl: no headless OpenGL" in r.stderr and "libegl1" in r.stderr
    assert not (REPO / "never.png").exists()


def test_egl_and_gl_do_not_share_a_process():
    """PyBullet's EGL plugin and OpenGL's context collide: the second of the two in one process is refused in one
    line, never a crash (a process of its own: this one may hold either)."""
    code = ("from sim.highway.renderer import Renderer\nfrom sim.highway.errors import RendererError\n"
            "from sim.highway.traffic import CarStates\nfrom sim.track import load_track\n"
            "t = load_track('oval', lanes=2)\nRenderer(t, 0, renderer='egl').render(0.0, 0.0, 0.0, CarStates.empty())\n"
            "try:\n    Renderer(t, 0, renderer='gl')\nexcept RendererError as e:\n    print(e)\n")
    if renderer_problem("gl"):
        pytest.skip(renderer_problem("gl"))
    r = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip().endswith("renderer gl cannot draw in a process where renderer egl has (their EGL "
                                     "contexts collide); use one of them, or another process"), r.stdout


@pytest.mark.parametrize("renderer", ["numba", "gl"])
def test_the_gymnasium_environment_takes_the_renderer(renderer):
    if renderer_problem(renderer):
        pytest.skip(renderer_problem(renderer))
    env = gym.make("drivestudio/Highway-v0", track="oval", lanes=2, cars=0, renderer=renderer, width=140, height=105)
    try:
        obs, _ = env.reset(seed=3)
        for _ in range(3):
            obs, *_ = env.step(np.array([0.0, 0.3, 0.0], dtype=np.float32))
        assert obs.shape == (105, 140, 3) and obs.dtype == np.uint8 and obs.std() > 10
    finally:
        env.close()


@pytest.mark.parametrize("renderer", ["numba", "gl"])
def test_a_dataset_records_the_renderer_that_drew_it(renderer, tmp_path):
    if renderer_problem(renderer):
        pytest.skip(renderer_problem(renderer))
    plugin = worlds.get("highway")
    config = WorldConfig(camera=CameraConfig(width=70, height=53), renderer=renderer)
    options = plugin.generate_options(config, {"tracks": "oval", "lane_counts": "2", "car_range": "0-0"})
    cfg = GenerateConfig(frames=6, episode_frames=3, renderer=renderer, warmup=0.0, options=options)
    manifest = generate(tmp_path / "ds", cfg, workers=1, show_progress=False, log=lambda *a: None)
    assert manifest["complete"] and read_manifest(tmp_path / "ds")["renderer"] == renderer
