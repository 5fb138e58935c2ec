"""The values of the sidewalk's command-line options: obstacle densities or files, behavioural-mode lists, and
PathError as a one-line usage error."""
from __future__ import annotations

import math

from core.declaration import DeclarationError
from core.worlds.sidewalk import SIDEWALK
from drivestudio.errors import UsageError
from sim.sidewalk.errors import PathError

DEFAULT_DENSITY = 4.0      # obstacles per 100 m


class one_line:
    """PathError (bad paths, obstacle files, modes) as the application's UsageError: one line, exit status 2.
    (drivestudio/errors.py does not list sim.sidewalk.errors.PathError yet.)"""

    def __enter__(self):
        return self

    def __exit__(self, kind, value, tb):
        if kind is not None and issubclass(kind, PathError):
            raise UsageError(str(value)) from None
        return False



def obstacles_value(text):
    """--obstacles: a density (obstacles per 100 m), 'none', or an obstacle file."""
    if text is None:
        return DEFAULT_DENSITY
    if str(text).lower() == "none":
        return 0.0
    try:
        v = float(text)
    except ValueError:
        return str(text)   # a file, read and checked by the world
    if not math.isfinite(v) or not 0.0 <= v <= 12.0:
        raise UsageError(f"--obstacles must be a density from 0 to 12 per 100 m, 'none' or an obstacle file, got "
                         f"{text!r}")
    return v


def mode_list(text: str | None) -> list[str]:
    """--modes: the modes named (None: all); a list that names none or an unknown mode is a usage error."""
    try:
        return list(SIDEWALK.mode_list(text))
    except DeclarationError as e:
        raise UsageError(str(e)) from None
