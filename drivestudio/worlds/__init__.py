"""The wiring of each declared world into the application: how to build it from options, its expert, the drivers
of its models, its metrics, the episodes `generate` records. One module per world in this package (a class named
Plugin), found by name; a world made at run time (a test's) is added with `register(plugin)`.

Everything generic (the loop, the bridge, datasets, models, training, the CLI verbs) talks to a world only through
its WorldDeclaration (core/worlds/) and its Plugin here. docs/architecture.md walks through adding a world.
"""
from __future__ import annotations

import importlib
import os
import pkgutil
from dataclasses import dataclass, field

from core.declaration import WorldDeclaration
from drivestudio.errors import UsageError

_REGISTERED: dict[str, Plugin] = {}


@dataclass(frozen=True)
class Episode:
    """One episode of a generation plan: its index, its frames and what the world's plan chose for it."""

    index: int
    frames: int
    seed: int
    params: dict = field(default_factory=dict)


class Plugin:
    """A world as the application sees it. Subclasses set `declaration` and override what their world supports."""

    declaration: WorldDeclaration
    expert_names: tuple[str, ...] = ("expert",)   # --model values that name the world's own drivers

    @property
    def name(self) -> str:
        return self.declaration.name

    # --- command-line options --------------------------------------------------------------------------------------
    def add_options(self, parser, verb: str) -> None:
        """Add this world's options for `verb` (render, generate, drive, serve, ...) to an argument group. Give
        every option default=None so that options of an unselected world can be told apart."""

    def options_given(self, args, verb: str) -> list[str]:
        """The flags of this world that `args` sets (to refuse them when another world is selected)."""
        return [flag for flag, dest in self._flags.get(verb, {}).items() if getattr(args, dest, None) is not None]

    _flags: dict = {}

    # --- worlds and drivers --------------------------------------------------------------------------------------
    def world(self, args, render: bool):
        """The world the options describe (render, drive, serve)."""
        raise UsageError(f"the {self.name} world cannot be built from options")

    def render(self, args) -> tuple[dict, dict]:
        """({camera: RGB image}, truth as JSON-able dict) of the scene the options describe (drivestudio render)."""
        raise UsageError(f"the {self.name} world cannot render from options")

    def driver(self, model: str, args, declaration: WorldDeclaration | None = None):
        """The driver for --model MODEL: one of expert_names or a checkpoint of this world. By default a
        checkpoint whose outputs are the world's action drives directly (drivestudio/drivers.py)."""
        return direct_driver(model, args, declaration or self.declaration)

    def supervisor(self, world, args):
        """What the world side does with the driver's command in `manual` mode or under correction: a function
        (obs, action) -> (applied action, operation mode), or None (the driver's command is applied)."""
        return None

    def metrics(self, world):
        """An object with observe(obs), add_time(stage, s), wall_time, report() and table()."""
        raise UsageError(f"the {self.name} world has no closed-loop metrics")

    def recorder(self, world, path, label: str):
        """A per-step callback that writes a video of the run (drive --record), with close(ok)."""
        if path:
            raise UsageError(f"the {self.name} world cannot record videos")
        return _NoRecorder()

    def overlay(self, images, record: dict, estimate: dict | None, label: str):
        """One RGB picture of a recorded step: its images beside truth and estimate (drivestudio overlay)."""
        raise UsageError(f"the {self.name} world draws no overlays")

    def overlay_error(self, record: dict, estimate: dict | None) -> float:
        """How wrong an estimate is, for --select worst (larger: worse)."""
        return 0.0

    def needs_frames(self, args) -> bool:
        """Whether an in-process run must render (a model reads frames; a video shows them)."""
        return True

    def describe_run(self, world, args) -> dict:
        """What a run's metrics.json records about the world (track, lanes, cars, ...)."""
        return {}

    def driver_args(self, args) -> list[str]:
        """Options the driver process of `drive` needs besides --shm, --model and --device."""
        return []

    # --- datasets ------------------------------------------------------------------------------------------------
    def declaration_for(self, options: dict) -> WorldDeclaration:
        """The declaration of the worlds a generation with these options builds (e.g. its camera size)."""
        return self.declaration

    def generate_options(self, args) -> dict:
        """The JSON-able options of this world that decide a dataset's content, validated."""
        return {}

    def plan(self, options: dict, frames: int, episode_frames: int, seed: int) -> list[Episode]:
        raise UsageError(f"the {self.name} world cannot generate datasets")

    def episode(self, ep: Episode, options: dict, renderer: str):
        """(world, expert driver, columns) for recording episode `ep`: columns(obs) gives the declaration's extra
        columns for a step."""
        raise UsageError(f"the {self.name} world cannot generate datasets")


class _NoRecorder:
    def __call__(self, rec) -> None:
        pass

    def close(self, ok: bool) -> None:
        pass


def direct_driver(model: str, args, declaration: WorldDeclaration):
    """A checkpoint of world `declaration` whose outputs are its action values, as a driver."""
    from drivestudio.commands.common import load_predictor_for
    from drivestudio.drivers import DirectDriver
    predictor = load_predictor_for(model, declaration.name, getattr(args, "device", "cpu"))
    return DirectDriver(predictor, declaration)


def register(plugin: Plugin) -> Plugin:
    _REGISTERED[plugin.name] = plugin
    from core import worlds
    worlds.register(plugin.declaration)
    return plugin


def _modules() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))


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
