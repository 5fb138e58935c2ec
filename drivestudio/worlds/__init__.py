"""The worlds of the application, found by name: one package per world in this folder (drivestudio/worlds/highway/,
drivestudio/worlds/sidewalk/) whose `Plugin` (drivestudio/worlds/base.py) wires it; a world made at run time (a
test's) is added with `register(plugin)`, one of another installed package with DRIVESTUDIO_WORLDS=module:Class.
docs/architecture.md walks through adding a world.
"""
from __future__ import annotations

import importlib
import os
import pkgutil

from core import worlds as declared
from drivestudio.errors import UsageError
from drivestudio.worlds.base import Episode, NoRecorder, Plugin, direct_driver

__all__ = ["Episode", "NoRecorder", "Plugin", "direct_driver", "register", "load_external", "names",
           "get", "all_plugins"]

_REGISTERED: dict[str, Plugin] = {}


def register(plugin: Plugin) -> Plugin:
    _REGISTERED[plugin.name] = plugin
    declared.register(plugin.declaration)
    return plugin


def _modules() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules(__path__) if m.ispkg and not m.name.startswith("_"))


def load_external() -> None:
    """Worlds of other packages: DRIVESTUDIO_WORLDS="module:Class,..." names their Plugin classes."""
    for ref in filter(None, (r.strip() for r in os.environ.get("DRIVESTUDIO_WORLDS", "").split(","))):
        module, _, name = ref.partition(":")
        try:
            plugin = getattr(importlib.import_module(module), name)()
        except (ImportError, AttributeError) as e:
            raise UsageError(f"DRIVESTUDIO_WORLDS names {ref!r}, which cannot be loaded ({e})") from None
        register(plugin)


def names() -> list[str]:
    return sorted(set(_modules()) | set(_REGISTERED))


def get(name: str) -> Plugin:
    if name in _REGISTERED:
        return _REGISTERED[name]
    if name in _modules():
        module = importlib.import_module(f"{__name__}.{name}")
        return register(module.Plugin())
    raise UsageError(f"unknown world {name!r} (worlds: {', '.join(names())})")


def all_plugins() -> list[Plugin]:
    return [get(n) for n in names()]
