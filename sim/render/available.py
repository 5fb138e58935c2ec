"""Whether this process can run a renderer: asked when a world's configuration names one, so that a renderer the
machine lacks is refused in one line before any work (sim/highway/config.py)."""
from __future__ import annotations

import functools
import importlib


@functools.cache
def renderer_problem(name: str) -> str | None:
    """Why renderer `name` (sim/camera.py RENDERERS) cannot draw in this process, in one line; None when it can.
    PyBullet's own renderers report their problems when their scene is made (sim/highway/bullet_scene.py)."""
    if name == "numba":
        try:
            importlib.import_module("numba")   # loaded here, once, as the renderer will load it
        except ImportError as e:
            return f"numba cannot be imported ({e}); pip install numba"
    if name == "gl":
        from sim.render.gl_context import gl_problem  # lazy: moderngl and EGL, for this renderer only
        return gl_problem()
    return None


_EGL_USER: list[str] = []   # the renderer that uses EGL in this process, once one does


def share_egl(name: str) -> str | None:
    """Renderer `name` ("egl" or "gl") is about to use EGL in this process: None when it may, else why not. A frame
    of OpenGL between two frames of PyBullet's EGL plugin crashes the process, even with OpenGL's context current only
    while it draws: the two renderers do not share one."""
    if _EGL_USER and _EGL_USER[0] != name:
        return f"renderer {name} cannot draw in a process where renderer {_EGL_USER[0]} has (their EGL contexts " \
               "collide); use one of them, or another process"
    if not _EGL_USER:
        _EGL_USER.append(name)
    return None
