"""The sidewalk's behavioural-mode lists as generate's plan reads them (obstacle densities and files are read by its
configuration's setting, sim/sidewalk/config.py)."""
from __future__ import annotations

from core.declaration import DeclarationError
from core.worlds.sidewalk import SIDEWALK
from drivestudio.errors import UsageError


def mode_list(text: str | None) -> list[str]:
    """--modes: the modes named (None: all); a list that names none or an unknown mode is a usage error."""
    try:
        return list(SIDEWALK.mode_list(text))
    except DeclarationError as e:
        raise UsageError(str(e)) from None
