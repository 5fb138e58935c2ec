"""The sidewalk world's wiring (docs/sidewalk.md): options, the world, its drivers (the experts of the three
behavioural modes, a deliberately poor driver, or a checkpoint driving directly), the operation modes (expert,
autonomous, correctional), closed-loop metrics, videos with both cameras and a top-down view, overlays, and the
plan of a balanced data-moment set."""
from __future__ import annotations

import math
import time

import numpy as np

from core.worlds.sidewalk import MODES, OPERATIONS, SIDEWALK
from drivestudio.errors import UsageError
from drivestudio.numbers import count, finite, non_negative
from drivestudio.worlds import Episode, Plugin

DEFAULT_PATH = "park"
DEFAULT_DENSITY = 4.0      # obstacles per 100 m
_NO_ESTIMATE = np.full(len(SIDEWALK.estimate_names), np.nan)


# --- drivers -----------------------------------------------------------------------------------------------------
class ExpertDriver:
    """The expert of the record's behavioural mode (controller/sidewalk/experts.py), on the truth record only."""

    name = "expert"

    def __init__(self):
        from controller.sidewalk import SidewalkExpert
        self.expert = SidewalkExpert()
        self.timings = {"control": 0.0}

    def act(self, percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        action = self.expert.action(percept.record)
        self.timings["control"] += time.perf_counter() - t0
        return action, _NO_ESTIMATE


class PoorDriver:
    """A deliberately poor driver (controller/sidewalk/poor.py), to exercise correctional operation."""

    name = "poor"

    def __init__(self, seed: int = 0):
        from controller.sidewalk import PoorDriver as Poor
        self.driver = Poor(seed)
        self.timings = {"control": 0.0}

    def act(self, percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        action = np.array(self.driver.act(percept.record))
        self.timings["control"] += time.perf_counter() - t0
        return action, _NO_ESTIMATE


class Supervisor:
    """What the world side applies under each operation mode: expert (the expert's command; also whenever the
    bridge's driver_mode is "manual"), autonomous (the driver's), correctional (the driver's, until the
    correction rule of controller/sidewalk/correction.py hands over to the expert, and back). The world's record
    carries the operation mode of every command applied."""

    def __init__(self, world, operation: str):
        from controller.sidewalk import CorrectionRule, SidewalkExpert
        self.world, self.operation = world, operation
        self.expert, self.rule = SidewalkExpert(), CorrectionRule(dt=world.dt)

    def __call__(self, obs, action, driver_mode: str = "network"):
        expert = self.expert.action(obs.record)
        if driver_mode == "manual" or self.operation == "expert":
            name, applied = "expert", expert
        elif self.operation == "autonomous":
            name, applied = "autonomous", np.asarray(action, dtype=np.float64)
        else:
            driver = self.world.declaration.clip_action(action)
            correcting = self.rule.update(obs.record, tuple(driver), tuple(expert))
            name, applied = ("correctional", expert) if correcting else ("autonomous", driver)
        self.world.set_operation(name)
        return applied, name


class CorrectionalDriver:
    """In-process correctional operation for dataset episodes: the poor driver drives, the supervisor's rule lets
    the expert take over; the command returned is the one applied."""

    name = "poor+expert"

    def __init__(self, world, seed: int):
        self.poor = PoorDriver(seed)
        self.supervisor = Supervisor(world, "correctional")
        self.timings = {"control": 0.0}

    def act(self, percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        action, _ = self.poor.act(percept)
        applied, _ = self.supervisor(percept, action)
        self.timings["control"] += time.perf_counter() - t0
        return applied, _NO_ESTIMATE


# --- metrics and videos ------------------------------------------------------------------------------------------
class Metrics:
    """controller/sidewalk/metrics.py fed from the world's observations."""

    def __init__(self, world):
        from controller.sidewalk import SidewalkMetrics
        self.m = SidewalkMetrics(world.dt)

    def observe(self, obs) -> None:
        self.m.update(obs.record)

    def __getattr__(self, name):
        return getattr(self.m, name)

    def __setattr__(self, name, value):
        if name == "m":
            object.__setattr__(self, name, value)
        else:
            setattr(self.m, name, value)


class Recorder:
    """drive --record: per step, both cameras and a top-down view, with a line of what is happening (30 fps)."""

    def __init__(self, path, world, label: str):
        from drivestudio.outputs import VideoWriter
        from sim.sidewalk.topdown import TopDown
        self.writer = VideoWriter(path, fps=round(1 / world.dt))
        self.world, self.label = world, label
        h = world.declaration.camera("left").height
        self.top = TopDown(world.layout, size=h + (h % 2), span=14.0)

    def __call__(self, rec) -> None:
        obs = rec.obs
        left, right = obs.frames
        if left is None:
            return
        r = SIDEWALK.unpack(obs.record)
        lead = self.world.lead.state if self.world.lead is not None else None
        top = self.top.draw(r["x"], r["y"], r["yaw"], lead)
        a = np.asarray(rec.action, dtype=np.float64)
        text = (f"t {obs.t:5.1f} s  {MODES[r['behaviour']]}  {OPERATIONS[r['operation']]}  {r['speed']:4.2f} m/s  "
                f"steer {a[0]:.2f}  motor {a[1]:.2f}  {self.label}")
        self.writer.write(compose(left, right, top, text, r["collision"], r["correcting"]))

    def close(self, ok: bool) -> None:
        (self.writer.close if ok else self.writer.abort)()
        if ok:
            print(f"recorded {self.writer.frames} frames to {self.writer.path}")


def compose(left: np.ndarray, right: np.ndarray, top: np.ndarray | None, text: str, alarm: bool = False,
            correcting: bool = False) -> np.ndarray:
    """[left | right | top-down] over a status line (RGB)."""
    import cv2
    h = left.shape[0]
    parts = [left, right] + ([top[:h, :h]] if top is not None else [])
    row = np.concatenate(parts, axis=1)
    bar = np.full((24, row.shape[1], 3), (30, 30, 30), np.uint8)
    if correcting:
        bar[:] = (150, 110, 0)
    if alarm:
        bar[:] = (160, 30, 30)
    cv2.putText(bar, text, (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (235, 235, 235), 1, cv2.LINE_AA)
    out = np.concatenate([row, bar], axis=0)
    if out.shape[1] % 2:
        out = np.concatenate([out, out[:, -1:]], axis=1)
    return out


# --- option values -----------------------------------------------------------------------------------------------
class _one_line:
    """PathError (bad paths, obstacle files, modes) as the application's UsageError: one line, exit status 2.
    (drivestudio/errors.py does not list sim.sidewalk.errors.PathError yet.)"""

    def __enter__(self):
        return self

    def __exit__(self, kind, value, tb):
        from sim.sidewalk.errors import PathError
        if kind is not None and issubclass(kind, PathError):
            raise UsageError(str(value)) from None
        return False



def obstacles_value(text):
    """--obstacles: a density (obstacles per 100 m), 'none', or an obstacle file."""
    if text is None:
        return DEFAULT_DENSITY
    if str(text).lower() == "none":
        return 0.0
    try:
        v = float(text)
    except ValueError:
        return str(text)   # a file, read and checked by the world
    if not math.isfinite(v) or not 0.0 <= v <= 12.0:
        raise UsageError(f"--obstacles must be a density from 0 to 12 per 100 m, 'none' or an obstacle file, got "
                         f"{text!r}")
    return v


def mode_list(text: str | None) -> list[str]:
    modes = [m.strip() for m in (text or ",".join(MODES)).split(",") if m.strip()]
    unknown = [m for m in modes if m not in MODES]
    if unknown or not modes:
        raise UsageError(f"unknown behavioural mode {unknown[0] if unknown else text!r} (modes: {', '.join(MODES)})")
    return modes


# --- the plugin ----------------------------------------------------------------------------------------------------
class Plugin(Plugin):
    declaration = SIDEWALK
    expert_names = ("expert", "poor", "oracle")   # oracle: the expert, under the name `drive --shm` defaults to

    def __init__(self):
        self._flags = {}

    def _add(self, group, verb: str, *flags, **kw) -> None:
        """Add an option with default None; a flag another world already added for this verb (--width, --warmup,
        --procedural) is shared: it is recorded as this world's too, with that world's checks."""
        existing = group._option_string_actions.get(flags[0])
        if existing is not None:
            self._flags.setdefault(verb, {})[flags[0]] = existing.dest
            return
        action = group.add_argument(*flags, default=None, **kw)
        self._flags.setdefault(verb, {})[flags[0]] = action.dest

    def add_options(self, parser, verb: str) -> None:
        g = parser.add_argument_group("sidewalk world (--world sidewalk)")
        if verb in ("render", "drive", "serve"):
            self._add(g, verb, "--path", help="path preset (park, sidewalk, forest), path file or procedural:SEED "
                                              "(default park)")
            self._add(g, verb, "--mode", choices=MODES, help="behavioural mode (default direct)")
            self._add(g, verb, "--obstacles", help="obstacles per 100 m (default 4), 'none', or an obstacle file")
            self._add(g, verb, "--path-width", type=finite(1.5, 3.0),
                      help="path width [m], 1.5-3 (default: the path's)")
        if verb in ("drive", "serve"):
            self._add(g, verb, "--operation", choices=OPERATIONS,
                      help="expert, autonomous or correctional (default: expert for --model expert, correctional "
                           "otherwise)")
        if verb in ("render", "generate"):
            self._add(g, verb, "--width", type=count(16, 4096), help="frame width [px] (sidewalk: 336)")
            self._add(g, verb, "--height", type=count(16, 4096), help="frame height [px] (sidewalk: 188)")
            self._add(g, verb, "--fov", type=finite(10.0, 150.0),
                      help="vertical field of view [deg] (sidewalk: 56)")
        if verb == "render":
            self._add(g, verb, "--warmup", type=non_negative(3600.0),
                      help="simulated seconds the expert drives before the frame is taken")
        if verb == "generate":
            self._add(g, verb, "--modes", help="behavioural modes to cycle through, episode by episode (default "
                                               "direct,follow,furtive)")
            self._add(g, verb, "--paths", help="comma-separated paths: presets, files, procedural:SEED (default: "
                                               "every preset plus --procedural procedural paths)")
            self._add(g, verb, "--procedural", type=count(0, 1000),
                      help="procedural paths added to the default list (3)")
            self._add(g, verb, "--obstacles", help="obstacles per 100 m (default 4) or 'none'")
            self._add(g, verb, "--correctional", type=finite(0.0, 1.0),
                      help="share of episodes driven by the poor driver under the correction rule (default 0)")

    # --- worlds ----------------------------------------------------------------------------------------------------
    def _stereo(self, args):
        from sim.sidewalk.stereo import StereoConfig, with_size
        return with_size(StereoConfig(), getattr(args, "width", None), getattr(args, "height", None),
                         getattr(args, "fov", None))

    @staticmethod
    def _check_renderer(args) -> None:
        if getattr(args, "renderer", "tiny") == "egl":
            raise UsageError("the sidewalk world paints its frames with OpenCV (sim/sidewalk/painter.py); "
                             "--renderer egl does not apply to it")

    def world(self, args, render: bool):
        from sim.sidewalk.world import SidewalkConfig, SidewalkWorld
        self._check_renderer(args)
        with _one_line():
            return SidewalkWorld(SidewalkConfig(path=args.path or DEFAULT_PATH, path_width=args.path_width,
                                                seed=args.seed, mode=args.mode or "direct",
                                                obstacles=obstacles_value(args.obstacles), stereo=self._stereo(args),
                                                render=render))

    def render(self, args) -> tuple[dict, dict]:
        from drivestudio.loop import in_process, run_loop
        with self.world(args, render=False) as world:
            if args.warmup:
                run_loop(world, in_process(ExpertDriver()), args.warmup, render=False, when_lost="recover")
            obs = world.observe(render=True)
            truth = {**obs.truth, "t": obs.t, "path": world.path.ref, "style": world.path.style, "seed": world.seed,
                     "time_of_day": world.renderer.look.time, "stereo": world.config.stereo.describe()}
            return {"left": obs.frames[0], "right": obs.frames[1]}, truth

    def driver(self, model: str, args, declaration=None):
        if model in ("expert", "oracle"):
            return ExpertDriver()
        if model == "poor":
            return PoorDriver(getattr(args, "seed", None) or 0)
        from drivestudio.commands.common import load_predictor_for
        from drivestudio.drivers import DirectDriver
        predictor = load_predictor_for(model, self.name, getattr(args, "device", "cpu"))
        return DirectDriver(predictor, declaration or self.declaration, smooth=True)

    def operation(self, args) -> str:
        return getattr(args, "operation", None) or ("expert" if getattr(args, "model", None) in ("expert", "oracle")
                                                    else "correctional")

    def supervisor(self, world, args):
        return Supervisor(world, self.operation(args))

    def metrics(self, world):
        return Metrics(world)

    def recorder(self, world, path, label: str):
        if not path:
            return super().recorder(world, path, label)
        return Recorder(path, world, label)

    def needs_frames(self, args) -> bool:
        return args.model not in self.expert_names or bool(getattr(args, "record", None))

    def describe_run(self, world, args) -> dict:
        return {"path": world.path.ref, "path_length_m": round(world.path.length, 1),
                "path_width_m": world.path.width, "style": world.path.style, "mode": world.mode,
                "operation": self.operation(args), "obstacles": len(world.layout.obstacles), "seed": world.seed}

    def driver_args(self, args) -> list[str]:
        return ["--seed", str(args.seed)]

    # --- overlays ----------------------------------------------------------------------------------------------------
    def overlay(self, images, record: dict, estimate: dict | None, label: str):
        from drivestudio.worlds.sidewalk.overlay import overlay
        return overlay(images, record, estimate, label)

    def overlay_error(self, record: dict, estimate: dict | None) -> float:
        from drivestudio.worlds.sidewalk.overlay import overlay_error
        return overlay_error(record, estimate)

    # --- datasets ------------------------------------------------------------------------------------------------
    def generate_options(self, args) -> dict:
        from sim.sidewalk.paths import load_path
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
                   "width": stereo.width, "height": stereo.height, "fov": stereo.fov_deg}
        with _one_line():
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
        from sim.sidewalk.paths import preset_names
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
            out.append(Episode(k, base + (k < extra), ep_seed,
                               {"path": paths[(k // len(modes)) % len(paths)], "mode": modes[k % len(modes)],
                                "operation": operation}))
        return out

    def episode(self, ep: Episode, options: dict, renderer: str):
        from sim.sidewalk.stereo import StereoConfig
        from sim.sidewalk.world import SidewalkConfig, SidewalkWorld
        p = ep.params
        stereo = StereoConfig(width=options["width"], height=options["height"], fov_deg=options["fov"])
        world = SidewalkWorld(SidewalkConfig(path=p["path"], seed=ep.seed, mode=p["mode"],
                                             obstacles=options["obstacles"], stereo=stereo, render=False))
        driver = CorrectionalDriver(world, ep.seed) if p.get("operation") == "correctional" else ExpertDriver()

        def columns(obs) -> dict:
            return {"path": p["path"]}
        return world, driver, columns
