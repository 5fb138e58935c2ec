"""The base of every world's Plugin: how the application sees a world (docs/architecture.md).

A Plugin builds its world from command-line options, names its drivers (experts and checkpoints), its supervisor,
metrics and recorders, draws its overlays and plans the episodes `generate` records. Everything generic (the loop,
the bridge, datasets, models, training, the verbs) talks to a world only through its WorldDeclaration
(core/worlds/) and its Plugin.
"""
from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Protocol

from core.declaration import WorldDeclaration
from drivestudio.checkpoints import check_checkpoint, load_predictor_for
from drivestudio.driver_spec import DriverSpec, EstimateFilter, parse_driver
from drivestudio.drivers import DirectDriver
from drivestudio.errors import UsageError
from drivestudio.loop import Driver, Metrics, StepRecord, Supervisor, World
from perception.dataset_stats import AnyWorld, Coverage
from perception.mae_report import ReportLayout

if TYPE_CHECKING:
    from drivestudio.studio.kit import StudioKit


class WorldOptions:
    """The world-specific options of one verb's parser. Each world adds its own with `add`; a flag that two worlds
    share (--width, --warmup, ...) is added once, with the first world's help and checks, and belongs to both.
    Every option has default None, so that `given` can tell which flags of a world the user set."""

    def __init__(self, parser: argparse.ArgumentParser, verb: str):
        self.parser, self.verb = parser, verb
        self._dest: dict[str, str] = {}                # flag -> dest, of every world option added
        self._owned: dict[str, dict[str, str]] = {}    # world -> flag -> dest

    def group(self, title: str):
        return self.parser.add_argument_group(title)

    def add(self, world: str, group, *flags: str, **kw) -> None:
        flag = flags[0]
        if flag not in self._dest:
            self._dest[flag] = group.add_argument(*flags, default=None, **kw).dest
        self._owned.setdefault(world, {})[flag] = self._dest[flag]

    def owns(self, world: str, flag: str) -> bool:
        return flag in self._owned.get(world, {})

    def given(self, world: str, args) -> list[str]:
        """The flags of `world` that `args` sets."""
        return [f for f, dest in self._owned.get(world, {}).items() if getattr(args, dest, None) is not None]


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
    # the estimate filters a driver spec may name (`CKPT@name=value`, drivestudio/driver_spec.py)
    filters: Mapping[str, EstimateFilter] = MappingProxyType({})

    @property
    def name(self) -> str:
        return self.declaration.name

    # --- command-line options --------------------------------------------------------------------------------------
    def add_options(self, options: WorldOptions) -> None:
        """Add this world's options for `options.verb` (render, generate, drive, serve, ...) with options.add."""

    # --- worlds and drivers --------------------------------------------------------------------------------------
    def world(self, args, render: bool) -> World:
        """The world the options describe (render, drive, serve)."""
        raise UsageError(f"the {self.name} world cannot be built from options")

    def render(self, args) -> tuple[dict, dict]:
        """({camera: RGB image}, truth as JSON-able dict) of the scene the options describe (drivestudio render)."""
        raise UsageError(f"the {self.name} world cannot render from options")

    def own_model(self, model: str) -> bool:
        """Whether --model MODEL names a driver this world makes itself, not a checkpoint (highway: a trained
        policy, drivestudio/worlds/highway/policy.py); the generic checkpoint checks then leave it to check_model."""
        return False

    def parse_driver(self, text: str, option: str = "--model") -> DriverSpec:
        """The driver spec `text` (drivestudio/driver_spec.py), its filters checked against this world's."""
        return parse_driver(text, self.filters, self.expert_names, option)

    def check_driver(self, spec: DriverSpec) -> None:
        """Check a driver before any world starts: one of expert_names, a driver of own_model, or a checkpoint of
        this world; else one line and exit status 2."""
        if spec.source not in self.expert_names:
            check_checkpoint(spec.source, self.name)

    def resolve_args(self, args) -> None:
        """Before any work: check this world's options of a verb against --model (one line and exit status 2,
        UsageError) and settle those the model decides. By default there is nothing to do."""

    def driver(self, spec: DriverSpec, device: str = "cpu", declaration: WorldDeclaration | None = None,
               seed: int = 0) -> Driver:
        """The driver of `spec`: one of expert_names or a checkpoint of this world (on torch `device`), for a world
        of `declaration` (default: this world's); `seed` seeds a driver that draws. By default a checkpoint whose
        outputs are the world's action drives directly (drivestudio/drivers.py)."""
        return direct_driver(spec.source, device, declaration or self.declaration)

    def supervisor(self, world: World, args) -> Supervisor | None:
        """What the world side does with the driver's command in `manual` mode or under correction: a function
        (obs, action, driver_mode) -> (applied action, operation mode), or None (the command is applied)."""
        return None

    def metrics(self, world: World) -> Metrics:
        """The world's closed-loop metrics of a run."""
        raise UsageError(f"the {self.name} world has no closed-loop metrics")

    def recorder(self, world: World, path, label: str) -> Recorder:
        """A per-step callback that writes a video of the run (drive --record), with close(ok)."""
        if path:
            raise UsageError(f"the {self.name} world cannot record videos")
        return NoRecorder()

    def overlay(self, images, record: dict, estimate: dict | None, label: str):
        """One RGB picture of a recorded step: its images beside truth and estimate (drivestudio overlay)."""
        raise UsageError(f"the {self.name} world draws no overlays")

    def overlay_error(self, record: dict, estimate: dict | None) -> float:
        """How wrong an estimate is, for --select worst (larger: worse)."""
        return 0.0

    def needs_frames(self, spec: DriverSpec, record: bool) -> bool:
        """Whether an in-process run must render: a model reads frames, a video (`record`) shows them."""
        return spec.source not in self.expert_names or record

    def describe_run(self, world, args) -> dict:
        """What a run's metrics.json records about the world (track, lanes, cars, ...)."""
        return {}

    def studio(self) -> StudioKit:
        """How the studio shows this world and how a person drives it (drivestudio/studio/kit.py)."""
        raise UsageError(f"the studio does not show the {self.name} world")

    # --- reports -------------------------------------------------------------------------------------------------
    def evaluation_layout(self) -> ReportLayout:
        """How `evaluate` lays out the MAE report of this world's models (default: one column per output)."""
        return ReportLayout()

    def coverage(self) -> Coverage:
        """What `stats` reports of this world's datasets (default: label spread, modes, flags)."""
        return AnyWorld()

    # --- datasets ------------------------------------------------------------------------------------------------
    def declaration_for(self, options: dict) -> WorldDeclaration:
        """The declaration of the worlds a generation with these options builds (e.g. its camera size)."""
        return self.declaration

    def generate_options(self, args) -> dict:
        """The JSON-able options of this world that decide a dataset's content, validated."""
        return {}

    def plan(self, options: dict, frames: int, episode_frames: int, seed: int) -> list[Episode]:
        raise UsageError(f"the {self.name} world cannot generate datasets")

    def episode(self, ep: Episode, options: dict, renderer: str) -> tuple[World, Driver, Callable[..., dict]]:
        """(world, expert driver, columns) for recording episode `ep`: columns(obs) gives the declaration's extra
        columns for a step."""
        raise UsageError(f"the {self.name} world cannot generate datasets")


class Recorder(Protocol):
    """A video of a run: called with every StepRecord, closed once (ok: keep it; otherwise remove it)."""

    def __call__(self, rec: StepRecord) -> None: ...

    def close(self, ok: bool) -> None: ...


class NoRecorder:
    def __call__(self, rec: StepRecord) -> None:
        pass

    def close(self, ok: bool) -> None:
        pass


def direct_driver(model: str, device: str, declaration: WorldDeclaration) -> Driver:
    """A checkpoint of world `declaration` whose outputs are its action values, as a driver."""
    predictor = load_predictor_for(model, declaration.name, device)
    return DirectDriver(predictor, declaration)
