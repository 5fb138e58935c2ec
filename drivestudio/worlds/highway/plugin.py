"""The highway world's wiring: options, the world, the Chen driver over the oracle or a trained regressor, the
data-collection expert, closed-loop metrics, overlay videos and the generation plan."""
from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from controller.highway.metrics import HighwayMetrics
from core.conditions import CONDITION_COLUMN, SEEDED
from core.settings import SettingError
from core.worlds.highway import HIGHWAY, INDICATORS, MAX_LANES, REAR
from drivestudio.checkpoints import checkpoint_inset, load_predictor_for
from drivestudio.driver_spec import DriverSpec
from drivestudio.errors import UsageError
from drivestudio.loop import Driver, Observation, Supervisor, in_process, run_loop
from drivestudio.worlds import base
from drivestudio.worlds.base import Episode
from drivestudio.worlds.highway.aggregation_config import car_range
from drivestudio.worlds.highway.drivers import ORACLES, ChenDriver, ExpertDriver, chen_driver
from drivestudio.worlds.highway.filters import FILTERS
from drivestudio.worlds.highway.overlays import overlay_record
from drivestudio.worlds.highway.policy import PolicyDriver, is_policy, load_policy
from drivestudio.worlds.highway.video import OverlayRecorder
from perception.highway.overlay import mean_normalised_error
from perception.highway.stats import HighwayCoverage
from perception.highway.table3 import Table3Layout
from sim.camera import CameraConfig
from sim.highway.config import WorldConfig
from sim.mirror import INSET_FLAGS, inset_name, inset_options
from sim.track import load_track, preset_names

if TYPE_CHECKING:
    from drivestudio.studio.kit import StudioKit
    from sim.highway.world import World



# --- the plugin ----------------------------------------------------------------------------------------------------
class Plugin(base.Plugin):
    declaration = HIGHWAY
    expert_names = ("oracle", "oracle-extended", "expert")
    filters = FILTERS
    verbs = ("probe", "benchmark", "suite", "aggregate", "recipe", "ppo")

    # the settings each verb shows as flags; every other one is `--set NAME=VALUE`
    verb_settings = {"render": ("track", "lanes", "cars", "seed", "condition"),
                     "drive": ("track", "lanes", "cars", "seed", "scenario", "condition"),
                     "serve": ("track", "lanes", "cars", "seed", "scenario"),
                     "generate": ("condition",)}

    config_type = WorldConfig

    def add_options(self, options) -> None:
        if options.verb == "generate":
            g = options.group("highway world (--world highway)")
            options.add(self.name, g, "--tracks", help="comma-separated tracks: presets, files, procedural:SEED "
                        "(default: every preset plus --procedural procedural tracks)")
            options.add(self.name, g, "--procedural", type=int, help="procedural tracks added to the default list "
                        "(3; 0-1000)")
            options.add(self.name, g, "--lanes", help="lane counts to cycle through (default 1,2,3)",
                        dest="lane_counts")
            options.add(self.name, g, "--cars", help="AI cars per episode: N or a range A-B (default 12-30)",
                        dest="car_range")

    # --- worlds ----------------------------------------------------------------------------------------------------
    def settle(self, config: WorldConfig) -> WorldConfig:
        """The side views come with the mirror they sit below; a scripted scenario's route replaces the track, lanes,
        cars, seed and start (its file read and checked now: one line, before any work)."""
        if config.scenario is not None:
            from sim.highway.scripted import load_scripted  # lazy: the track library, only with a scenario
            config = load_scripted(config.scenario).configure(config)
        return replace(config, mirror=config.mirror or config.side_views)

    def fit_driver(self, config: WorldConfig, spec: DriverSpec) -> WorldConfig:
        """A checkpoint reads frames like the ones it learned: one that learned the mirror (and the side views) gets
        them, and insets it did not learn are refused."""
        model = spec.source
        if model in self.expert_names or is_policy(model):
            return config
        inset, asked = checkpoint_inset(model), config.inset
        if asked and asked != inset:
            how = f"with {_inset_options(inset)}" if inset else "without the mirror (--set mirror=false)"
            raise UsageError(f"{_inset_options(asked)}: {model} learned frames {_inset_words(inset)}; drive it {how}")
        mirror, side_views = INSET_FLAGS[inset]
        return replace(config, mirror=mirror, side_views=side_views)

    def world(self, config: WorldConfig) -> World:
        from sim.highway.world import World  # lazy: trimesh
        return World(config)

    def render(self, config: WorldConfig, warmup: float = 0.0, scenario: str | None = None) -> tuple[dict, dict]:
        from sim.highway.scenario import load_scenario  # lazy: with the world
        from sim.highway.world import World  # lazy: trimesh
        if scenario:
            # a scenario places its own cars and the host; the look and the camera are the configuration's
            world = World(replace(config, cars=0, render=False), scenario=load_scenario(scenario, lanes=config.lanes))
        else:
            world = self.world(replace(config, render=False))
        with world:
            if warmup:
                warm_up(world, warmup)
            obs = world.observe(render=True)
            return {"front": obs.frame}, obs.truth.as_dict()

    def own_model(self, model: str) -> bool:
        return is_policy(model)

    def check_driver(self, spec: DriverSpec) -> None:
        if is_policy(spec.source):
            if spec.filters:
                raise UsageError(f"{spec}: a policy reads the exact affordances; filters apply to checkpoints")
            load_policy(spec.source)   # opened and checked now: one line, exit 2
        else:
            super().check_driver(spec)

    def driver(self, spec: DriverSpec, device: str = "cpu", declaration=None, seed: int = 0) -> Driver:
        model = spec.source
        if is_policy(model):
            return PolicyDriver(model, device)
        if model in ORACLES or model == "expert":
            return ChenDriver(None, lookout=ORACLES.get(model, False))
        predictor = load_predictor_for(model, self.name, device)
        if declaration is not None and predictor.inset != declaration.cameras[0].inset:
            # the world is already running (a bridge, the studio): a model is not shown frames unlike its own
            want = f"with {_inset_options(predictor.inset)}" if predictor.inset else "without the mirror"
            raise UsageError(f"{model} learned frames {_inset_words(predictor.inset)} and this world's are "
                             f"{_inset_words(declaration.cameras[0].inset)}: start the world {want}")
        return chen_driver(spec, predictor)

    def supervisor(self, world, config, spec: DriverSpec | None) -> Supervisor:
        expert = ChenDriver(None)   # in "manual" mode the world-side oracle drives, as a human did in TORCS

        def supervise(obs: Observation, action: np.ndarray, mode: str) -> tuple[np.ndarray, str]:
            if mode == "manual":
                return expert.act(obs)[0], "manual"
            return action, "network"
        return supervise

    def metrics(self, world):
        return HighwayMetrics.of(world)

    @staticmethod
    def _estimate(estimate: dict | None):
        if estimate is None:
            return None, None
        est = np.array([estimate.get(n, 0.0) for n in INDICATORS])
        return est, estimate.get("lanes_left")

    def overlay(self, images, record: dict, estimate: dict | None, label: str) -> np.ndarray:
        truth = np.array([record[n] for n in INDICATORS], dtype=np.float64)
        est, ll = self._estimate(estimate)
        title = f"episode {record['episode']} frame {record['step']}  {record['track']}, {record['lanes']} lanes"
        rear = None if estimate is None else np.array([estimate.get(n, np.nan) for n in REAR], dtype=np.float64)
        return overlay_record(images[0], record, truth, est, title, ll, label, rear)

    def overlay_error(self, record: dict, estimate: dict | None) -> float:
        est, _ = self._estimate(estimate)
        if est is None:
            return 0.0
        return mean_normalised_error(np.array([record[n] for n in INDICATORS], dtype=np.float64), est)

    def evaluation_layout(self) -> Table3Layout:
        return Table3Layout()

    def coverage(self) -> HighwayCoverage:
        return HighwayCoverage()

    def describe_run(self, world, config, spec: DriverSpec | None) -> dict:
        named = {"condition": world.condition} if world.config.condition != SEEDED else {}
        return {"track": world.track.name, "lanes": world.track.lanes, "cars": world.config.cars,
                "mirror": world.config.mirror, "side_views": world.config.side_views, **named}

    def studio(self) -> StudioKit:
        from drivestudio.worlds.highway.studio import KIT  # lazy: the overlays and presets only for the studio
        return KIT

    def recorder(self, world, path, label: str):
        return OverlayRecorder(path, world, label)

    # --- datasets ------------------------------------------------------------------------------------------------
    def generate_options(self, config: WorldConfig, plan: dict) -> dict:
        lanes = _int_list(plan.get("lane_counts") or "1,2,3", "--lanes")
        if not lanes or any(not 1 <= n <= MAX_LANES for n in lanes):
            raise UsageError(f"--lanes must list lane counts from 1 to {MAX_LANES}")
        try:
            cars = car_range(plan.get("car_range") or "12-30")
        except SettingError as e:
            raise UsageError(f"--{e}") from None
        tracks = [t.strip() for t in (plan.get("tracks") or "").split(",") if t.strip()]
        if plan.get("tracks") is not None and not tracks:
            raise UsageError("--tracks names no track")
        procedural = 3 if plan.get("procedural") is None else plan["procedural"]
        if not 0 <= procedural <= 1000:
            raise UsageError(f"--procedural must be an integer from 0 to 1000, got {procedural}")
        options = {"tracks": tracks, "procedural": procedural, "lanes": list(lanes), "cars": list(cars),
                   "width": config.camera.width, "height": config.camera.height, "fov": config.camera.fov_deg,
                   **inset_options(config.inset),
                   # only when named: a dataset of the seeded look keeps the plan (and the resumption) of before
                   **({"condition": config.condition} if config.condition != SEEDED else {})}
        for track in self.track_list(options, 0):   # a bad track fails here, in one line, before any work
            for n in set(lanes):
                load_track(track, lanes=n)
        return options

    def declaration_for(self, options: dict):
        decl = HIGHWAY.with_camera("front", options["height"], options["width"],
                                   inset_name(bool(options.get("mirror")), bool(options.get("side_views"))))
        return decl.with_column(CONDITION_COLUMN) if options.get("condition") else decl

    @staticmethod
    def track_list(options: dict, seed_: int) -> list[str]:
        if options["tracks"]:
            return list(options["tracks"])
        return preset_names() + [f"procedural:{seed_ * 1000 + i}" for i in range(options["procedural"])]

    def plan(self, options: dict, frames: int, episode_frames: int, seed_: int) -> list[Episode]:
        """Episode k drives lane count lane_slot(k, L) on track (k div L) mod T: every track meets every lane count,
        and the split rule's every-tenth episodes (validation, test) cycle through every lane count too."""
        tracks = self.track_list(options, seed_)
        lanes = options["lanes"]
        lo, hi = options["cars"]
        n = -(-frames // episode_frames)
        episodes = []
        for k in range(n):
            rng = np.random.default_rng([seed_, k, 0x6E4])
            cars = int(rng.integers(lo, hi + 1))
            ep_seed = int(rng.integers(2**31 - 1))
            episodes.append(Episode(k, min(episode_frames, frames - k * episode_frames), ep_seed,
                                    {"track": tracks[(k // len(lanes)) % len(tracks)],
                                     "lanes": int(lanes[lane_slot(k, len(lanes))]),
                                     "cars": cars}))
        return episodes

    def episode(self, ep: Episode, options: dict, renderer: str):
        from sim.highway.world import World  # lazy: trimesh
        camera = CameraConfig(width=options["width"], height=options["height"], fov_deg=options["fov"])
        p = ep.params
        world = World(WorldConfig(track=p["track"], lanes=p["lanes"], cars=p["cars"], seed=ep.seed,
                                  renderer=renderer, camera=camera, render=False,
                                  mirror=bool(options.get("mirror")), side_views=bool(options.get("side_views")),
                                  condition=options.get("condition", SEEDED)))
        expert = ExpertDriver(p["lanes"], world.track.lane_width, ep.seed, world.dt)

        def columns(obs) -> dict:
            return {"track": p["track"], "perturbation": expert.label,
                    "cars": obs.truth.cars.astype(np.float32).tolist(), "condition": world.condition}
        return world, expert, columns


def lane_slot(k: int, n: int) -> int:
    """Which of n lane counts episode k drives: k mod n, shifted by one every ten episodes when n shares a factor
    with 10 (2, 4, 5 ...), whose every-tenth episodes would otherwise meet only some lane counts (with four, the
    validation split only two). With n coprime to 10 (1, 3, 7 ...) the plain cycle already meets them all, and the
    datasets made with it keep their plan."""
    return (k + k // 10) % n if math.gcd(10, n) > 1 else k % n


def warm_up(world: World, seconds: float) -> Observation:
    """Let the traffic settle: the oracle drives the host car for `seconds`, nothing is rendered."""
    return run_loop(world, in_process(ChenDriver(None)), seconds, render=False)


def _int_list(text: str, flag: str) -> tuple[int, ...]:
    try:
        return tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise UsageError(f"{flag}: expected comma-separated integers, got '{text}'") from None


def _inset_options(inset: str) -> str:
    return "--set side_views=true" if inset == "mirror+sides" else "--set mirror=true"


def _inset_words(inset: str) -> str:
    return {"": "without the rear-view mirror", "mirror": "with the rear-view mirror",
            "mirror+sides": "with the rear-view mirror and the side views"}[inset]
