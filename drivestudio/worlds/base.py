"""The base of every world's Plugin: how the application sees a world (docs/architecture.md).

A Plugin names its world's typed configuration (core/settings.py) and the settings each verb shows, builds the
world of a configuration, names its drivers (experts and checkpoints), its supervisor,
metrics and recorders, draws its overlays and plans the episodes `generate` records. Everything generic (the loop,
the bridge, datasets, models, training, the verbs) talks to a world only through its WorldDeclaration
(core/worlds/) and its Plugin.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Protocol

from core.declaration import WorldDeclaration
from core.settings import MAX_SEED, setting
from drivestudio.checkpoints import check_checkpoint, load_predictor_for
from drivestudio.driver_spec import DriverSpec, EstimateFilter, parse_driver
from drivestudio.drivers import DirectDriver
from drivestudio.errors import UsageError
from drivestudio.loop import Driver, Metrics, StepRecord, Supervisor, World
from perception.dataset_stats import AnyWorld, Coverage
from perception.mae_report import ReportLayout

if TYPE_CHECKING:
    from drivestudio.studio.kit import StudioKit


@dataclass
class NoConfig:
    """The configuration of a world that declares none: the seed alone."""

    seed: int = setting(0, "seed of the world", low=0, high=MAX_SEED)
    render: bool = True


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

    # --- configuration ---------------------------------------------------------------------------------------------
    # the world's typed configuration (core/settings.py): a dataclass whose settings the verbs show as options
    config_type: type = NoConfig
    # per verb (render, drive, serve, generate), the settings of config_type it shows, by dotted path
    verb_settings: Mapping[str, tuple[str, ...]] = MappingProxyType({})
    # the verbs that serve this world alone (modules of drivestudio/commands/), listed under it in --help
    verbs: tuple[str, ...] = ()

    def add_options(self, options) -> None:
        """Options of this world that are not settings of its configuration (generate's plan), added for
        `options.verb` with options.add (drivestudio/commands/world_options.py); `generate_options` gets them."""

    def settle(self, config):
        """The configuration with what its settings imply (the highway's side views bring the mirror)."""
        return config

    # --- worlds and drivers --------------------------------------------------------------------------------------
    def world(self, config) -> World:
        """The world of a configuration (render, drive, serve, the studio); `config.render` says whether it
        renders."""
        raise UsageError(f"the {self.name} world cannot be built from a configuration")

    def render(self, config, warmup: float = 0.0, scenario: str | None = None) -> tuple[dict, dict]:
        """({camera: RGB image}, truth as JSON-able dict) of the scene of a configuration after `warmup` simulated
        seconds of the world's own driver (drivestudio render); a scenario file where the world has them."""
        raise UsageError(f"the {self.name} world cannot render from a configuration")

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
            check_checkpoint(spec.source, self.name, self.expert_names)

    def fit_driver(self, config, spec: DriverSpec):
        """Before any work: the configuration a driver needs (the highway's mirror for a model that learned it),
        or one line and exit status 2 (UsageError) where it cannot drive this one. By default the configuration."""
        return config

    def driver(self, spec: DriverSpec, device: str = "cpu", declaration: WorldDeclaration | None = None,
               seed: int = 0) -> Driver:
        """The driver of `spec`: one of expert_names or a checkpoint of this world (on torch `device`), for a world
        of `declaration` (default: this world's); `seed` seeds a driver that draws. By default a checkpoint whose
        outputs are the world's action drives directly (drivestudio/drivers.py)."""
        return direct_driver(spec.source, device, declaration or self.declaration)

    def supervisor(self, world: World, config, spec: DriverSpec | None) -> Supervisor | None:
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

    def describe_run(self, world, config, spec: DriverSpec | None) -> dict:
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

    def generate_options(self, config, plan: dict) -> dict:
        """The JSON-able options of this world that decide a dataset's content, validated: from its configuration
        (camera, insets) and `plan`, its own options of generate by destination (and `renderer`)."""
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
