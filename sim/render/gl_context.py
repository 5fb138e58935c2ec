"""The process's one OpenGL context: headless EGL through moderngl (Mesa's llvmpipe on a CPU, the driver's EGL on a
GPU), made on first use and shared by every GL renderer of the process.

llvmpipe rasterises on LP_NUM_THREADS threads besides the caller's; a small frame is drawn fastest on the
calling thread alone (docs/benchmarks.md), and parallel work (generation workers, a pool) runs one process a core, so
an unset LP_NUM_THREADS is set to 0 here before Mesa reads it.
"""
from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import sys

THREADS_VARIABLE = "LP_NUM_THREADS"


@contextlib.contextmanager
def _quiet():
    """Mesa and EGL may print warnings on stderr while a context is made; keep them out of our output."""
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    try:
        yield
    finally:
        ctypes.CDLL(None).fflush(None)
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


@functools.cache
def _make():
    """(context, None) or (None, why not), once per process."""
    try:
        import moderngl  # lazy: only the GL renderer needs it, and it loads libEGL
    except ImportError as e:
        return None, f"moderngl is not installed ({e})"
    os.environ.setdefault(THREADS_VARIABLE, "0")
    try:
        with _quiet():
            # moderngl's stub types each keyword setting as a dict, where the library takes a string
            ctx = moderngl.create_standalone_context(backend="egl", require=450)  # type: ignore[arg-type]
    except Exception as e:   # EGL fails in many ways: no library, no device, no GL 4.5
        reason = " ".join(str(e).split()) or type(e).__name__
        return None, f"no headless OpenGL 4.5 context through EGL ({reason}); on Debian: apt-get install -y " \
                     "libegl1 libegl-mesa0 libgl1-mesa-dri"
    return ctx, None


def gl_problem() -> str | None:
    """Why this process cannot render with OpenGL, in one line; None when it can."""
    return _make()[1]


def gl_context():
    """The process's moderngl context (RuntimeError with gl_problem()'s line when there is none)."""
    ctx, problem = _make()
    if ctx is None:
        raise RuntimeError(problem)
    return ctx


def describe() -> str:
    """The GL renderer and version of the context, e.g. 'llvmpipe (LLVM 15.0.6, 256 bits), 4.5 (Core Profile) ...'."""
    info = gl_context().info
    return f"{info['GL_RENDERER']}, {info['GL_VERSION']}"
