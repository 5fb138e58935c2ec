"""The sidewalk world's wiring (docs/sidewalk.md): options, the world, its drivers (the experts of the three
behavioural modes, a deliberately poor driver, or a checkpoint driving directly), the operation modes (expert,
autonomous, correctional), closed-loop metrics, videos with both cameras and a top-down view, overlays, and the
plan of a balanced data-moment set."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from controller.sidewalk.correction import RULES
from core.worlds.sidewalk import MODES, OPERATIONS, SIDEWALK
from drivestudio.checkpoints import load_predictor_for
from drivestudio.driver_spec import DriverSpec
from drivestudio.drivers import DirectDriver
from drivestudio.errors import UsageError
from drivestudio.loop import in_process, run_loop
from drivestudio.numbers import count, finite, non_negative
from drivestudio.worlds import base
from drivestudio.worlds.base import Episode, WorldOptions
from drivestudio.worlds.sidewalk.drivers import (
    CorrectionalDriver,
    ExpertDriver,
    PerturbedDriver,
    PoorDriver,
    Supervisor,
)
from drivestudio.worlds.sidewalk.metrics import Metrics
from drivestudio.worlds.sidewalk.options import mode_list, obstacles_value, one_line
from drivestudio.worlds.sidewalk.video import Recorder
from sim.sidewalk.paths import load_path, preset_names

if TYPE_CHECKING:
    from drivestudio.studio.kit import StudioKit

DEFAULT_PATH = "park"


# --- the plugin ----------------------------------------------------------------------------------------------------
class Plugin(base.Plugin):
    declaration = SIDEWALK
    expert_names = ("expert", "poor", "oracle")   # oracle: the expert, under the name `drive --shm` defaults to

    def add_options(self, options: WorldOptions) -> None:
        verb = options.verb
        g = options.group("sidewalk world (--world sidewalk)")
        if verb in ("render", "drive", "serve"):
            options.add(self.name, g, "--path", help="path preset (park, sidewalk, forest), path file or "
                        "procedural:SEED (default park)")
            options.add(self.name, g, "--mode", choices=MODES, help="behavioural mode (default direct)")
            options.add(self.name, g, "--obstacles",
                        help="obstacles per 100 m (default 4), 'none', or an obstacle file")
            options.add(self.name, g, "--path-width", type=finite(1.5, 3.0),
                        help="path width [m], 1.5-3 (default: the path's)")
        if verb in ("drive", "serve"):
            options.add(self.name, g, "--operation", choices=OPERATIONS,
                        help="expert, autonomous or correctional (default: expert for --model expert, correctional "
                        "otherwise)")
            options.add(self.name, g, "--rule", choices=RULES,
                        help="the correction rule of correctional operation: safety (take over for leaving the path, "
                        "an imminent collision, a stalled car; default) or strict (also for deviating from the "
                        "expert)")
        if verb in ("render", "generate"):
            options.add(self.name, g, "--width", type=count(16, 4096), help="frame width [px] (sidewalk: 336)")
            options.add(self.name, g, "--height", type=count(16, 4096), help="frame height [px] (sidewalk: 188)")
            options.add(self.name, g, "--fov", type=finite(10.0, 150.0),
                        help="vertical field of view [deg] (sidewalk: 56)")
        if verb == "render":
            options.add(self.name, g, "--warmup", type=non_negative(3600.0),
                        help="simulated seconds the expert drives before the frame is taken")
        if verb == "generate":
            options.add(self.name, g, "--modes", help="behavioural modes to cycle through, episode by episode (default "
                        "direct,follow,furtive)")
            options.add(self.name, g, "--paths", help="comma-separated paths: presets, files, procedural:SEED "
                        "(default: every preset plus --procedural procedural paths)")
            options.add(self.name, g, "--procedural", type=count(0, 1000),
                        help="procedural paths added to the default list (3)")
            options.add(self.name, g, "--obstacles", help="obstacles per 100 m (default 4) or 'none'")
            options.add(self.name, g, "--correctional", type=finite(0.0, 1.0),
                        help="share of episodes driven by the poor driver under the correction rule (default 0)")
            options.add(self.name, g, "--perturbed", type=finite(0.0, 1.0),
                        help="share of the other episodes whose expert's steering is knocked aside now and then, "
                        "its recoveries labelled (default 0; docs/sidewalk.md)")

    # --- worlds ----------------------------------------------------------------------------------------------------
    def _stereo(self, args):
        from sim.sidewalk.stereo import StereoConfig, with_size  # lazy: the renderer, not for --help
        return with_size(StereoConfig(), getattr(args, "width", None), getattr(args, "height", None),
                         getattr(args, "fov", None))

    @staticmethod
    def _check_renderer(args) -> None:
        if getattr(args, "renderer", "tiny") == "egl":
            raise UsageError("the sidewalk world paints its frames with OpenCV (sim/sidewalk/painter.py); "
                             "--renderer egl does not apply to it")

    def world(self, args, render: bool):
        from sim.sidewalk.world import SidewalkConfig, SidewalkWorld  # lazy: the renderer, not for --help
        self._check_renderer(args)
        with one_line():
            return SidewalkWorld(SidewalkConfig(path=args.path or DEFAULT_PATH, path_width=args.path_width,
                                                seed=args.seed, mode=args.mode or "direct",
                                                obstacles=obstacles_value(args.obstacles), stereo=self._stereo(args),
                                                render=render))

    def render(self, args) -> tuple[dict, dict]:
        with self.world(args, render=False) as world:
            if args.warmup:
                run_loop(world, in_process(ExpertDriver()), args.warmup, render=False, when_lost="recover")
            obs = world.observe(render=True)
            truth = {**obs.truth, "t": obs.t, "path": world.path.ref, "style": world.path.style, "seed": world.seed,
                     "time_of_day": world.renderer.look.time, "stereo": world.config.stereo.describe()}
            return {"left": obs.frames[0], "right": obs.frames[1]}, truth

    def driver(self, spec: DriverSpec, device: str = "cpu", declaration=None, seed: int = 0):
        model = spec.source
        if model in ("expert", "oracle"):
            return ExpertDriver()
        if model == "poor":
            return PoorDriver(seed)
        predictor = load_predictor_for(model, self.name, device)
        return DirectDriver(predictor, declaration or self.declaration, smooth=True)

    def operation(self, args) -> str:
        return getattr(args, "operation", None) or ("expert" if getattr(args, "model", None) in ("expert", "oracle")
                                                    else "correctional")

    def supervisor(self, world, args):
        return Supervisor(world, self.operation(args), getattr(args, "rule", None) or "safety")

    def metrics(self, world):
        return Metrics(world)

    def recorder(self, world, path, label: str):
        if not path:
            return super().recorder(world, path, label)
        return Recorder(path, world, label)

    def describe_run(self, world, args) -> dict:
        return {"path": world.path.ref, "path_length_m": round(world.path.length, 1),
                "path_width_m": world.path.width, "style": world.path.style, "mode": world.mode,
                "operation": self.operation(args), "rule": getattr(args, "rule", None) or "safety",
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
    def generate_options(self, args) -> dict:
        self._check_renderer(args)
        modes = mode_list(args.modes)
        density = obstacles_value(args.obstacles)
        if isinstance(density, str):
            raise UsageError("generate takes --obstacles as a density per 100 m or 'none' (an obstacle file belongs "
                             "to one path: use drive or render)")
        paths = [t.strip() for t in (args.paths or "").split(",") if t.strip()]
        if args.paths is not None and not paths:
            raise UsageError("--paths names no path")
        stereo = self._stereo(args)
        options = {"modes": modes, "paths": paths, "procedural": 3 if args.procedural is None else args.procedural,
                   "obstacles": density, "correctional": args.correctional or 0.0,
                   **({"perturbed": args.perturbed} if args.perturbed else {}),
                   "width": stereo.width, "height": stereo.height, "fov": stereo.fov_deg}
        with one_line():
            for ref in self.path_list(options, 0):   # a bad path fails here, in one line, before any work
                load_path(ref)
        return options

    def declaration_for(self, options: dict):
        h, w = options["height"], options["width"]
        return SIDEWALK.with_camera("left", h, w).with_camera("right", h, w)

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
        from sim.sidewalk.stereo import StereoConfig  # lazy: the renderer, not for --help
        from sim.sidewalk.world import SidewalkConfig, SidewalkWorld  # lazy: as above
        p = ep.params
        stereo = StereoConfig(width=options["width"], height=options["height"], fov_deg=options["fov"])
        world = SidewalkWorld(SidewalkConfig(path=p["path"], seed=ep.seed, mode=p["mode"],
                                             obstacles=options["obstacles"], stereo=stereo, render=False))
        drivers = {"correctional": CorrectionalDriver, "perturbed": PerturbedDriver}
        make = drivers.get(p.get("operation", "expert"))
        driver = make(world, ep.seed) if make else ExpertDriver()

        def columns(obs) -> dict:
            return {"path": p["path"]}
        return world, driver, columns
