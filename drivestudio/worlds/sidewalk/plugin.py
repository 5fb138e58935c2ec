"""The sidewalk world's wiring (docs/sidewalk.md): options, the world, its drivers (the experts of the three
behavioural modes, a deliberately poor driver, or a checkpoint driving directly), the operation modes (expert,
autonomous, correctional), closed-loop metrics, videos with both cameras and a top-down view, overlays, and the
plan of a balanced data-moment set."""
from __future__ import annotations

import math
from dataclasses import replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from controller.sidewalk import SidewalkMetrics
from core.conditions import CONDITION_COLUMN, SEEDED
from core.worlds.sidewalk import SIDEWALK
from drivestudio.checkpoints import load_predictor_for
from drivestudio.driver_spec import DriverSpec
from drivestudio.drivers import DirectDriver
from drivestudio.errors import UsageError
from drivestudio.loop import in_process, run_loop
from drivestudio.worlds import base
from drivestudio.worlds.base import Episode
from drivestudio.worlds.sidewalk.drivers import (
    CorrectionalDriver,
    ExpertDriver,
    PerturbedDriver,
    PoorDriver,
    Supervisor,
    correction_rule,
)
from drivestudio.worlds.sidewalk.options import mode_list
from drivestudio.worlds.sidewalk.video import Recorder
from sim.sidewalk.config import DEFAULT_DENSITY, SidewalkConfig, StereoConfig, obstacles_value
from sim.sidewalk.paths import load_path, preset_names

if TYPE_CHECKING:
    from drivestudio.studio.kit import StudioKit



# --- the plugin ----------------------------------------------------------------------------------------------------
class Plugin(base.Plugin):
    declaration = SIDEWALK
    expert_names = ("expert", "poor", "oracle")   # oracle: the expert, under the name `drive --shm` defaults to

    config_type = SidewalkConfig
    verbs = ("autonomy", "study")
    # the settings each verb shows as flags; every other one is `--set NAME=VALUE`
    verb_settings = {
        "render": ("path", "mode", "obstacles", "seed"),
        "drive": ("path", "mode", "obstacles", "seed", "operation", "rule"),
        "serve": ("path", "mode", "obstacles", "seed", "operation", "rule"),
    }

    def add_options(self, options) -> None:
        if options.verb == "generate":
            g = options.group("sidewalk world (--world sidewalk)")
            options.add(self.name, g, "--modes", help="behavioural modes to cycle through, episode by episode (default "
                        "direct,follow,furtive)")
            options.add(self.name, g, "--paths", help="comma-separated paths: presets, files, procedural:SEED "
                        "(default: every preset plus --procedural procedural paths)")
            options.add(self.name, g, "--procedural", type=int, help="procedural paths added to the default list "
                        "(3; 0-1000)")
            options.add(self.name, g, "--obstacles", help="obstacles per 100 m (default 4) or 'none'")
            options.add(self.name, g, "--correctional", type=float,
                        help="share of episodes driven by the poor driver under the correction rule, 0-1 (default 0)")
            options.add(self.name, g, "--perturbed", type=float,
                        help="share of the other episodes whose expert's steering is knocked aside now and then, "
                        "its recoveries labelled, 0-1 (default 0; docs/sidewalk.md)")

    # --- worlds ----------------------------------------------------------------------------------------------------
    def world(self, config: SidewalkConfig):
        from sim.sidewalk.world import SidewalkWorld  # lazy: the renderer, not for --help
        return SidewalkWorld(config)

    def render(self, config: SidewalkConfig, warmup: float = 0.0, scenario: str | None = None) -> tuple[dict, dict]:
        if scenario:
            raise UsageError("a scenario file describes a highway scene (--world highway)")
        with self.world(replace(config, render=False)) as world:
            if warmup:
                run_loop(world, in_process(ExpertDriver()), warmup, render=False, when_lost="recover")
            obs = world.observe(render=True)
            truth = {**obs.truth, "t": obs.t, "path": world.path.ref, "style": world.path.style, "seed": world.seed,
                     "time_of_day": world.renderer.look.time, "condition": world.condition,
                     "stereo": world.config.stereo.describe()}
            return {"left": obs.frames[0], "right": obs.frames[1]}, truth

    def driver(self, spec: DriverSpec, device: str = "cpu", declaration=None, seed: int = 0):
        model = spec.source
        if model in ("expert", "oracle"):
            return ExpertDriver()
        if model == "poor":
            return PoorDriver(seed)
        predictor = load_predictor_for(model, self.name, device)
        return DirectDriver(predictor, declaration or self.declaration, smooth=True)

    @staticmethod
    def operation(config: SidewalkConfig, spec: DriverSpec | None) -> str:
        """The configuration's operation mode, or by default expert for the expert and correctional for any other
        driver (None: one that attaches over the bridge)."""
        expert = spec is not None and spec.source in ("expert", "oracle")
        return config.operation or ("expert" if expert else "correctional")

    def supervisor(self, world, config: SidewalkConfig, spec: DriverSpec | None):
        return Supervisor(world, self.operation(config, spec), config.rule)

    def metrics(self, world):
        return SidewalkMetrics(world.dt, correction=partial(correction_rule, world))

    def recorder(self, world, path, label: str):
        if not path:
            return super().recorder(world, path, label)
        return Recorder(path, world, label)

    def describe_run(self, world, config: SidewalkConfig, spec: DriverSpec | None) -> dict:
        return {"path": world.path.ref, "path_length_m": round(world.path.length, 1),
                "path_width_m": world.path.width, "style": world.path.style, "mode": world.mode,
                "operation": self.operation(config, spec), "rule": config.rule,
                "obstacles": len(world.layout.obstacles), "seed": world.seed}

    def studio(self) -> StudioKit:
        from drivestudio.worlds.sidewalk.studio import KIT  # lazy: the overlays and presets only for the studio
        return KIT

    # --- overlays ----------------------------------------------------------------------------------------------------
    def overlay(self, images, record: dict, estimate: dict | None, label: str):
        from drivestudio.worlds.sidewalk.overlay import overlay  # lazy: the drawing, not for --help
        return overlay(images, record, estimate, label)

    def overlay_error(self, record: dict, estimate: dict | None) -> float:
        from drivestudio.worlds.sidewalk.overlay import overlay_error  # lazy: as for overlay()
        return overlay_error(record, estimate)

    # --- datasets ------------------------------------------------------------------------------------------------
    def generate_options(self, config: SidewalkConfig, plan: dict) -> dict:
        modes = mode_list(plan.get("modes"))
        density = DEFAULT_DENSITY if plan.get("obstacles") is None else obstacles_value(plan["obstacles"])
        if isinstance(density, str):
            raise UsageError("generate takes --obstacles as a density per 100 m or 'none' (an obstacle file belongs "
                             "to one path: use drive or render)")
        paths = [t.strip() for t in (plan.get("paths") or "").split(",") if t.strip()]
        if plan.get("paths") is not None and not paths:
            raise UsageError("--paths names no path")
        procedural = 3 if plan.get("procedural") is None else plan["procedural"]
        if not 0 <= procedural <= 1000:
            raise UsageError(f"--procedural must be an integer from 0 to 1000, got {procedural}")
        shares = {k: plan.get(k) or 0.0 for k in ("correctional", "perturbed")}
        for k, v in shares.items():
            if not math.isfinite(v):
                raise UsageError(f"--{k}: must be a finite number, got {v}")
            if not 0.0 <= v <= 1.0:
                raise UsageError(f"--{k}: must be in [0, 1], got {v:g}")
        stereo = config.stereo
        options = {"modes": modes, "paths": paths, "procedural": procedural, "obstacles": density,
                   "correctional": shares["correctional"],
                   **({"perturbed": shares["perturbed"]} if shares["perturbed"] else {}),
                   "width": stereo.width, "height": stereo.height, "fov": stereo.fov_deg,
                   # only when named: a dataset of the seeded look keeps the plan (and the resumption) of before
                   **({"condition": config.condition} if config.condition != SEEDED else {})}
        for ref in self.path_list(options, 0):   # a bad path fails here, in one line (PathError), before any work
            load_path(ref)
        return options

    def declaration_for(self, options: dict):
        h, w = options["height"], options["width"]
        decl = SIDEWALK.with_camera("left", h, w).with_camera("right", h, w)
        return decl.with_column(CONDITION_COLUMN) if options.get("condition") else decl

    @staticmethod
    def path_list(options: dict, seed_: int) -> list[str]:
        if options["paths"]:
            return list(options["paths"])
        return preset_names() + [f"procedural:{seed_ * 1000 + i}" for i in range(options["procedural"])]

    def plan(self, options: dict, frames: int, episode_frames: int, seed_: int) -> list[Episode]:
        """Episode k drives mode k mod M on path (k div M) mod P. The modes are balanced: the episodes are a
        multiple of M (at least M, so a small set holds every mode), equally long (to a frame; --episode-frames is
        the most an episode takes), and with three modes the split rule's every-tenth episode cycles through them
        too (10 = 1 mod 3). Every path meets every mode."""
        paths, modes = self.path_list(options, seed_), options["modes"]
        m = len(modes)
        n = max(-(-frames // episode_frames), m)
        n = -(-n // m) * m
        base, extra = divmod(frames, n)
        out = []
        for k in range(n):
            rng = np.random.default_rng([seed_, k, 0x5DE])
            ep_seed = int(rng.integers(2**31 - 1))
            operation = "correctional" if rng.uniform() < options["correctional"] else "expert"
            if operation == "expert" and options.get("perturbed") and rng.uniform() < options["perturbed"]:
                operation = "perturbed"   # drawn after the others: a plan without it is the plan it always was
            out.append(Episode(k, base + (k < extra), ep_seed,
                               {"path": paths[(k // len(modes)) % len(paths)], "mode": modes[k % len(modes)],
                                "operation": operation}))
        return out

    def episode(self, ep: Episode, options: dict, renderer: str):
        from sim.sidewalk.world import SidewalkWorld  # lazy: the renderer, not for --help
        p = ep.params
        stereo = StereoConfig(width=options["width"], height=options["height"], fov_deg=options["fov"])
        world = SidewalkWorld(SidewalkConfig(path=p["path"], seed=ep.seed, mode=p["mode"],
                                             obstacles=options["obstacles"], stereo=stereo, render=False,
                                             condition=options.get("condition", SEEDED)))
        drivers = {"correctional": CorrectionalDriver, "perturbed": PerturbedDriver}
        make = drivers.get(p.get("operation", "expert"))
        driver = make(world, ep.seed) if make else ExpertDriver()

        def columns(obs) -> dict:
            return {"path": p["path"], "condition": world.condition}
        return world, driver, columns
