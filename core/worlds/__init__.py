"""The declared worlds (core/declaration.py), one module per world, found by name.

    from core import worlds
    decl = worlds.get("highway")          # imports core.worlds.highway and returns its declaration
    worlds.names()                        # every world this installation knows

A world module defines one WorldDeclaration in upper case (HIGHWAY in highway.py); a world made at run time
(a test's, a plug-in's) is added with `register(decl)`.
"""
from __future__ import annotations

import importlib
import pkgutil

from core.declaration import DeclarationError, WorldDeclaration

_REGISTERED: dict[str, WorldDeclaration] = {}


def register(decl: WorldDeclaration) -> WorldDeclaration:
    """Make a declaration known by name (replacing an earlier one of the same name)."""
    if not isinstance(decl, WorldDeclaration):
        raise TypeError("register() takes a WorldDeclaration")
    _REGISTERED[decl.name] = decl
    return decl


def _modules() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))


def names() -> list[str]:
    return sorted(set(_modules()) | set(_REGISTERED))


def get(name: str) -> WorldDeclaration:
    """The declaration of world `name`, or DeclarationError naming the worlds there are."""
    if name in _REGISTERED:
        return _REGISTERED[name]
    if isinstance(name, str) and name in _modules():
        module = importlib.import_module(f"{__name__}.{name}")
        decl = getattr(module, name.upper(), None)
        if isinstance(decl, WorldDeclaration):
            return register(decl)
    raise DeclarationError(f"unknown world {name!r} (worlds: {', '.join(names())})")
