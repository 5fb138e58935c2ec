"""Errors that mean a refusal of what the user asked for (one line on stderr, exit status 2) or a run that failed on
its way because a peer died or stopped answering (one line, exit status 1); docs/errors.md has the table."""
from __future__ import annotations

import sys


class UsageError(ValueError):
    """A bad combination of options, found after parsing."""


class RunError(RuntimeError):
    """A run that failed on its way (a worker died, a peer went away or never answered): one line, exit status 1."""


# (module, class) of the errors that are the user's to fix; looked up only among modules already imported,
# since an exception of a class can exist only once its module is loaded (and the error path must not pay for
# importing torch)
_INPUT = (("core.inputs", "InputError"), ("sim.highway.errors", "RendererError"),
          ("sim.highway.errors", "TrafficError"), ("perception.shards", "DatasetError"),
          ("perception.checkpoint", "CheckpointError"), ("perception.training", "TrainingError"),
          ("core.files", "OutputError"), ("core.declaration", "DeclarationError"),
          ("shm_bridge.errors", "ProtocolMismatch"), ("shm_bridge.errors", "BadName"),
          ("shm_bridge.errors", "Refused"), ("perception.memory", "BatchTooLarge"),
          ("core.settings", "SettingError"))
_RUNTIME = (("shm_bridge.errors", "BridgeError"),)


def _loaded(pairs) -> tuple[type[BaseException], ...]:
    out = []
    for module, name in pairs:
        mod = sys.modules.get(module)
        if mod is not None and hasattr(mod, name):
            out.append(getattr(mod, name))
    return tuple(out)


def input_errors() -> tuple[type[BaseException], ...]:
    return (UsageError,) + _loaded(_INPUT)


def runtime_errors() -> tuple[type[BaseException], ...]:
    """Failures of a run rather than of its input (a peer process died)."""
    return (RunError,) + _loaded(_RUNTIME)


def refuse(prog: str, error: BaseException) -> int:
    """A tool's refusal: one line on stderr, `PROG: error: WHY`; returns the exit status (2)."""
    print(f"{prog}: error: {error}", file=sys.stderr)
    return 2
