"""The highway world's wiring: options, the world, the Chen driver over the oracle or a trained regressor, the
data-collection expert, closed-loop metrics, overlay videos and the generation plan."""
from __future__ import annotations

import time

import numpy as np

from core.worlds.highway import FRAME, HIGHWAY, INDICATORS, MAX_LANES
from drivestudio.errors import UsageError
from drivestudio.numbers import count, finite, non_negative
from drivestudio.worlds import Episode, Plugin

DEFAULT_CARS = 12
START_SPEED = 15.0          # [m/s]
ESTIMATE = tuple(HIGHWAY.estimate_names)
_ESTIMATE_INDEX = {n: i for i, n in enumerate(ESTIMATE)}
_GAPS = [i for i, n in enumerate(ESTIMATE) if n.startswith("dist_")]


# --- drivers -----------------------------------------------------------------------------------------------------
class ChenDriver:
    """Perception (a trained regressor, or the truth itself for the oracle: perfect perception, the upper bound
    every network is compared with) and the Chen controller. The controller is made on the first frame, when the
    lane count is known."""

    def __init__(self, predictor=None, smoothing: float = 0.0, gap_hold: float = 0.0):
        self.predictor = predictor
        self.smoothing, self.gap_hold = smoothing, gap_hold
        self.timings = {"perception": 0.0, "control": 0.0}
        self.controller = None
        self._i_speed, self._i_lanes = HIGHWAY.index("speed"), HIGHWAY.index("lanes")
        self._slots = [] if predictor is None else [(i, _ESTIMATE_INDEX[n]) for i, n in
                                                    enumerate(predictor.outputs) if n in _ESTIMATE_INDEX]
        self._smoothed = self._held = None

    @property
    def name(self) -> str:
        return "oracle" if self.predictor is None else self.predictor.name

    def estimate(self, percept) -> np.ndarray:
        """The estimate record (the 14 indicators and lanes_left; NaN where the model has no output)."""
        if self.predictor is None:
            est = np.full(len(ESTIMATE), np.nan)
            est[:len(INDICATORS)] = percept.record[:len(INDICATORS)]
            est[_ESTIMATE_INDEX["lanes_left"]] = percept.record[HIGHWAY.index("lanes_left")]
            return est
        values = self.predictor(percept.frames[0])
        est = np.full(len(ESTIMATE), np.nan)
        for i, j in self._slots:
            est[j] = values[i]
        if self.smoothing > 0:   # exponential smoothing of the estimate (an option, docs/controller.md)
            if self._smoothed is not None:
                est = np.where(np.isfinite(self._smoothed), self.smoothing * self._smoothed +
                               (1 - self.smoothing) * est, est)
            self._smoothed = est
        if self.gap_hold > 0:   # the gaps: a car coming closer at once, one going away slowly (docs/controller.md)
            if self._held is not None:
                est[_GAPS] = np.fmin(est[_GAPS], self.gap_hold * self._held + (1 - self.gap_hold) * est[_GAPS])
            self._held = est[_GAPS].copy()
        return est

    def act(self, percept) -> tuple[np.ndarray, np.ndarray]:
        from controller.highway import ChenController
        t0 = time.perf_counter()
        est = self.estimate(percept)
        t1 = time.perf_counter()
        lanes = int(percept.record[self._i_lanes])
        if self.controller is None or self.controller.lanes != lanes:
            self.controller = ChenController(lanes)
        indicators = np.nan_to_num(est[:len(INDICATORS)], nan=0.0)   # a 13-output model: fast = 0
        action = self.controller.act(indicators, float(percept.record[self._i_speed]))
        self.timings["perception"] += t1 - t0
        self.timings["control"] += time.perf_counter() - t1
        return action.as_array(), est


class ExpertDriver:
    """The data-collection expert (controller/highway/expert.py): the Chen controller on the true indicators with seeded
    perturbations; `label` names the perturbation acting on the last step."""

    name = "expert"

    def __init__(self, lanes: int, lane_width: float, seed_: int, dt: float):
        from controller.highway.expert import PerturbedExpert
        self.expert = PerturbedExpert(lanes, lane_width, seed_, dt=dt)
        self.label = "none"
        self.timings = {"control": 0.0}
        self._i_speed, self._i_d = HIGHWAY.index("speed"), HIGHWAY.index("d")

    def act(self, percept) -> tuple[np.ndarray, np.ndarray]:
        r = percept.record
        action, self.label = self.expert.act(r[:len(INDICATORS)], float(r[self._i_speed]), float(r[self._i_d]))
        est = np.full(len(ESTIMATE), np.nan)
        est[:len(INDICATORS)] = r[:len(INDICATORS)]
        return action.as_array(), est


# --- metrics -------------------------------------------------------------------------------------------------------
class HighwayMetrics:
    """controller/highway/metrics.py's ClosedLoopMetrics, fed from the highway's observations."""

    def __init__(self, world):
        from controller.highway.metrics import ClosedLoopMetrics
        self.m = ClosedLoopMetrics(world.track.length, world.dt)
        self.world = world

    def observe(self, obs) -> None:
        t = obs.truth
        gaps = self.world.track.gap(t.ego[3], t.cars[:, 3]) if len(t.cars) else np.zeros(0)
        self.m.update(t.speed, t.lanes_left, t.in_lane, obs.collision, obs.off_road, gaps)

    def __getattr__(self, name):
        return getattr(self.m, name)

    def __setattr__(self, name, value):
        if name in ("m", "world"):
            object.__setattr__(self, name, value)
        else:
            setattr(self.m, name, value)


class OverlayRecorder:
    """drive --record: every step's overlay (truth and the driver's estimate) into an mp4."""

    def __init__(self, path, world, label: str):
        from drivestudio.outputs import VideoWriter
        self.writer = VideoWriter(path) if path else None
        self.world, self.label = world, label

    def __call__(self, rec) -> None:
        if self.writer is not None:
            from drivestudio.worlds.highway.overlays import overlay_observation
            t = rec.obs.truth
            title = f"t {rec.obs.t:5.1f} s  {self.world.track.name}, {t.lanes} lanes, {t.speed:4.1f} m/s"
            estimate = None if self.label == "oracle" else np.asarray(rec.estimate)[:len(INDICATORS)]
            ll = None if self.label == "oracle" else rec.estimate[_ESTIMATE_INDEX["lanes_left"]]
            self.writer.write(overlay_observation(rec.obs, estimate, self.world.track, title,
                                                  None if ll is None or not np.isfinite(ll) else float(ll),
                                                  label=self.label))

    def close(self, ok: bool) -> None:
        if self.writer is not None:
            (self.writer.close if ok else self.writer.abort)()
            if ok:
                print(f"recorded {self.writer.frames} overlays to {self.writer.path}")


# --- the plugin ----------------------------------------------------------------------------------------------------
class Plugin(Plugin):
    declaration = HIGHWAY
    expert_names = ("oracle", "expert")

    def __init__(self):
        self._flags = {}

    def _add(self, group, verb: str, *flags, **kw) -> None:
        action = group.add_argument(*flags, default=None, **kw)
        self._flags.setdefault(verb, {})[flags[0]] = action.dest

    def add_options(self, parser, verb: str) -> None:
        g = parser.add_argument_group("highway world (--world highway)")
        if verb in ("render", "drive", "serve"):
            self._add(g, verb, "--track", help="track preset, track file or procedural:SEED (default oval)")
            self._add(g, verb, "--lanes", type=count(1, MAX_LANES), help="lane count 1-4 (default: the "
                      "track's)")
            self._add(g, verb, "--cars", type=count(0, 300),
                      help=f"AI cars driven by SUMO (default {DEFAULT_CARS})")
            self._add(g, verb, "--start-speed", type=non_negative(60.0),
                      help=f"host car's speed at the start [m/s] (default {START_SPEED:g})")
        if verb == "drive":
            self._add(g, verb, "--smoothing", type=finite(0.0, 0.95),
                      help="exponential smoothing of a model's estimates before the controller, 0-0.95 (default 0: "
                           "none; docs/controller.md)")
            self._add(g, verb, "--gap-hold", type=finite(0.0, 0.95),
                      help="hold a model's gap estimates (dist_*): a shorter gap at once, a longer one smoothed "
                           "with this factor, 0-0.95 (default 0: none; docs/controller.md)")
        if verb in ("render", "generate"):
            self._add(g, verb, "--width", type=count(16, 4096), help=f"frame width [px] (default {FRAME[1]})")
            self._add(g, verb, "--height", type=count(16, 4096), help=f"frame height [px] (default {FRAME[0]})")
            self._add(g, verb, "--fov", type=finite(10.0, 150.0),
                      help="vertical field of view [deg] (default 60)")
        if verb == "render":
            self._add(g, verb, "--warmup", type=non_negative(3600.0),
                      help="simulated seconds to drive before the frame is taken (without a scenario)")
        if verb == "generate":
            self._add(g, verb, "--tracks", help="comma-separated tracks: presets, files, procedural:SEED "
                                                "(default: every preset plus --procedural procedural tracks)")
            self._add(g, verb, "--procedural", type=count(0, 1000),
                      help="procedural tracks added to the default list (3)")
            self._add(g, verb, "--lanes", help="lane counts to cycle through (default 1,2,3)", dest="lane_counts")
            self._add(g, verb, "--cars", help="AI cars per episode: N or a range A-B (default 12-30)",
                      dest="car_range")

    # --- worlds ----------------------------------------------------------------------------------------------------
    def config(self, args, render: bool, **extra):
        from sim.camera import CameraConfig
        from sim.highway.world import WorldConfig
        camera = CameraConfig(width=getattr(args, "width", None) or FRAME[1],
                              height=getattr(args, "height", None) or FRAME[0],
                              fov_deg=getattr(args, "fov", None) or 60.0)
        return WorldConfig(track=args.track or "oval", lanes=args.lanes, seed=args.seed,
                           cars=DEFAULT_CARS if args.cars is None else args.cars, renderer=args.renderer,
                           render=render, camera=camera,
                           start_speed=START_SPEED if args.start_speed is None else args.start_speed, **extra)

    def world(self, args, render: bool):
        from sim.highway.world import World
        return World(self.config(args, render))

    def render(self, args) -> tuple[dict, dict]:
        from sim.highway.scenario import load_scenario
        from sim.highway.world import World, WorldConfig
        if args.scenario:
            if args.track or args.warmup:
                raise UsageError("--track and --warmup go without a scenario file (a scenario places its own cars)")
            cfg = self.config(args, render=False)
            scenario = load_scenario(args.scenario, lanes=args.lanes)
            world = World(WorldConfig(renderer=args.renderer, camera=cfg.camera, cars=0), scenario=scenario)
        else:
            world = self.world(args, render=False)
        with world:
            if args.warmup:
                warm_up(world, args.warmup)
            obs = world.observe(render=True)
            return {"front": obs.frame}, obs.truth.as_dict()

    def driver(self, model: str, args, declaration=None):
        if model in ("oracle", "expert"):
            return ChenDriver(None)
        from drivestudio.commands.common import load_predictor_for
        predictor = load_predictor_for(model, self.name, getattr(args, "device", "cpu"))
        return ChenDriver(predictor, smoothing=getattr(args, "smoothing", None) or 0.0,
                          gap_hold=getattr(args, "gap_hold", None) or 0.0)

    def supervisor(self, world, args):
        expert = ChenDriver(None)   # in "manual" mode the world-side oracle drives, as a human did in TORCS

        def supervise(obs, action, mode: str):
            if mode == "manual":
                return expert.act(obs)[0], "manual"
            return action, "network"
        return supervise

    def metrics(self, world):
        return HighwayMetrics(world)

    @staticmethod
    def _estimate(estimate: dict | None):
        if estimate is None:
            return None, None
        est = np.array([estimate.get(n, 0.0) for n in INDICATORS])
        return est, estimate.get("lanes_left")

    def overlay(self, images, record: dict, estimate: dict | None, label: str):
        from drivestudio.worlds.highway.overlays import overlay_record
        truth = np.array([record[n] for n in INDICATORS], dtype=np.float64)
        est, ll = self._estimate(estimate)
        title = f"episode {record['episode']} frame {record['step']}  {record['track']}, {record['lanes']} lanes"
        return overlay_record(images[0], record, truth, est, title, ll, label)

    def overlay_error(self, record: dict, estimate: dict | None) -> float:
        from perception.highway.overlay import mean_normalised_error
        est, _ = self._estimate(estimate)
        if est is None:
            return 0.0
        return mean_normalised_error(np.array([record[n] for n in INDICATORS], dtype=np.float64), est)

    def needs_frames(self, args) -> bool:
        return args.model not in self.expert_names or bool(getattr(args, "record", None))

    def describe_run(self, world, args) -> dict:
        return {"track": world.track.name, "lanes": world.track.lanes, "cars": world.config.cars}

    def driver_args(self, args) -> list[str]:
        out = ["--smoothing", str(args.smoothing)] if getattr(args, "smoothing", None) else []
        return out + (["--gap-hold", str(args.gap_hold)] if getattr(args, "gap_hold", None) else [])

    def recorder(self, world, path, label: str):
        return OverlayRecorder(path, world, label)

    # --- datasets ------------------------------------------------------------------------------------------------
    def generate_options(self, args) -> dict:
        from sim.track import load_track
        lanes = _int_list(args.lane_counts or "1,2,3", "--lanes")
        if not lanes or any(not 1 <= n <= MAX_LANES for n in lanes):
            raise UsageError(f"--lanes must list lane counts from 1 to {MAX_LANES}")
        cars = _range(args.car_range or "12-30")
        if not 0 <= cars[0] <= cars[1] <= 300:
            raise UsageError("--cars must be from 0 to 300 (and A <= B)")
        tracks = [t.strip() for t in (args.tracks or "").split(",") if t.strip()]
        if args.tracks is not None and not tracks:
            raise UsageError("--tracks names no track")
        options = {"tracks": tracks, "procedural": 3 if args.procedural is None else args.procedural,
                   "lanes": list(lanes), "cars": list(cars), "width": args.width or FRAME[1],
                   "height": args.height or FRAME[0], "fov": 60.0 if args.fov is None else args.fov}
        for track in self.track_list(options, 0):   # a bad track fails here, in one line, before any work
            for n in set(lanes):
                load_track(track, lanes=n)
        return options

    def declaration_for(self, options: dict):
        return HIGHWAY.with_camera("front", options["height"], options["width"])

    @staticmethod
    def track_list(options: dict, seed_: int) -> list[str]:
        if options["tracks"]:
            return list(options["tracks"])
        from sim.track import preset_names
        return preset_names() + [f"procedural:{seed_ * 1000 + i}" for i in range(options["procedural"])]

    def plan(self, options: dict, frames: int, episode_frames: int, seed_: int) -> list[Episode]:
        """Episode k drives lane count k mod L on track (k div L) mod T: every track meets every lane count, and
        with three lane counts the split rule's every-tenth episode cycles through them too (10 = 1 mod 3)."""
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
                                     "lanes": int(lanes[k % len(lanes)]),
                                     "cars": cars}))
        return episodes

    def episode(self, ep: Episode, options: dict, renderer: str):
        from sim.camera import CameraConfig
        from sim.highway.world import World, WorldConfig
        camera = CameraConfig(width=options["width"], height=options["height"], fov_deg=options["fov"])
        p = ep.params
        world = World(WorldConfig(track=p["track"], lanes=p["lanes"], cars=p["cars"], seed=ep.seed,
                                  renderer=renderer, camera=camera, render=False, start_speed=START_SPEED))
        expert = ExpertDriver(p["lanes"], world.track.lane_width, ep.seed, world.dt)

        def columns(obs) -> dict:
            return {"track": p["track"], "perturbation": expert.label,
                    "cars": obs.truth.cars.astype(np.float32).tolist()}
        return world, expert, columns


def warm_up(world, seconds: float):
    """Let the traffic settle: the oracle drives the host car for `seconds`, nothing is rendered."""
    from drivestudio.loop import in_process, run_loop
    return run_loop(world, in_process(ChenDriver(None)), seconds, render=False)


def _int_list(text: str, flag: str) -> tuple[int, ...]:
    try:
        return tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise UsageError(f"{flag}: expected comma-separated integers, got '{text}'") from None


def _range(text: str) -> tuple[int, int]:
    try:
        lo, _, hi = text.partition("-")
        lo_i = int(lo)
        return (lo_i, int(hi) if hi else lo_i)
    except ValueError:
        raise UsageError(f"expected N or A-B for --cars, got '{text}'") from None

