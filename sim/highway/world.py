"""The world: a track, the host car, the other cars, the camera and the exact ground truth, stepped together.

world.step(action) -> Observation(frame, truth, t). The same object serves dataset generation, the
shared-memory server, the Gymnasium environment and the CLI's probe/render.

A static scenario (sim/highway/scenario.py, given as `scenario=`) places constant-speed cars for probe and render; a
scripted one (the configuration's `scenario` file, sim/highway/scripted.py) sets the route and the host's start and
drives its cars through SUMO by its events (sim/highway/scenario_run.py): every reset replays it, at its own seed.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from core.conditions import CONDITION_COLUMN, SEEDED, pick
from core.worlds.highway import HIGHWAY, Action
from sim.collision import overlaps
from sim.highway.conditions import condition_of
from sim.highway.config import WorldConfig
from sim.highway.renderer import Renderer
from sim.highway.scenario import Scenario
from sim.highway.scenario_run import ScenarioRun
from sim.highway.scripted import ScriptedScenario, load_scripted
from sim.highway.sumo_traffic import SumoTraffic
from sim.highway.traffic import CarStates, ScriptedTraffic
from sim.highway.truth import GroundTruth, ground_truth, truth_record
from sim.highway.vehicle import VehicleState, step_vehicle
from sim.track import Track, load_track

LOST_MARGIN = 6.0  # [m] beyond the road edge the host car is lost and the episode ends


@dataclass
class Observation:
    frame: np.ndarray | None        # (height, width, 3) uint8 RGB, None when rendering is off
    truth: GroundTruth
    t: float                        # [s] simulated time
    collision: bool = False         # the host car touches another car now
    off_road: bool = False          # the host car's centre is beyond a road edge now
    lost: bool = False              # so far off the road that the episode cannot go on

    # what the world-independent loop, bridge and recorders read (docs/architecture.md)
    @property
    def frames(self) -> tuple:
        """One image per camera of the declaration: the front camera's."""
        return (self.frame,)

    @property
    def record(self) -> np.ndarray:
        """The truth record, float64 in the order of the highway's declaration."""
        return truth_record(self.truth, self.collision, self.off_road)

    @property
    def end(self) -> str | None:
        """Why the episode cannot go on (None: it can)."""
        return "host lost" if self.lost else None


class World:
    """The highway world. `declaration` is HIGHWAY with the camera size of this world's configuration."""

    def __init__(self, config: WorldConfig | None = None, scenario: Scenario | None = None):
        config = config or WorldConfig()
        self.script: ScriptedScenario | None = None
        if scenario is None and config.scenario is not None:
            self.script = load_scripted(config.scenario)
            config = self.script.configure(config)
        self.config = config
        cam = config.camera
        self.declaration = HIGHWAY.with_camera("front", cam.height, cam.width, config.inset)
        if config.condition != SEEDED:   # a world of named conditions records each frame's
            self.declaration = self.declaration.with_column(CONDITION_COLUMN)
        self.dt = config.dt
        self.scenario = scenario
        if scenario is not None:
            self.track: Track = scenario.track
            self.seed = scenario.seed
        elif self.script is not None:
            self.track, self.seed = self.script.track, self.script.seed
        else:
            self.track = load_track(config.track, lanes=config.lanes, lane_width=config.lane_width)
            self.seed = config.seed
        self.timings = {"render": 0.0, "physics": 0.0, "traffic": 0.0, "truth": 0.0}
        self._renderer: Renderer | None = None
        self._renderer_seed: int | None = None
        self._traffic: ScriptedTraffic | SumoTraffic | None = None   # None once closed
        self._run: ScenarioRun | None = None
        self.last_cars = CarStates.empty()   # the cars of the last observation
        self.ego = VehicleState()
        self.t = 0.0
        self.reset(self.seed)

    # --- lifecycle -----------------------------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> Observation:
        if seed is not None:
            self.seed = int(seed)
        self.t = 0.0
        if self._traffic is not None:
            self._traffic.close()
        if self.scenario is not None:
            self.ego = replace(self.scenario.ego)
            cars = self.scenario.cars
            self._traffic = ScriptedTraffic(self.track, [c.s for c in cars], [c.d for c in cars],
                                            [c.speed for c in cars], seed=self.seed)
        elif self.script is not None:
            self.seed = self.script.seed
            self._run = ScenarioRun(self.script, self.config)
            self.ego = self._run.host_start()
            self._traffic = self._run.traffic(self.ego_pose(), self.ego.speed)
        else:
            rng = np.random.default_rng([self.seed, 0xE60])
            lane = int(rng.integers(0, self.track.lanes))
            if self.config.start_lane is not None:
                lane = int(self.config.start_lane)
            self.ego = VehicleState(s=0.0, d=float(self.track.lane_centres[lane]), speed=self.config.start_speed)
            self._traffic = self._make_traffic()
        return self.observe()

    def _make_traffic(self) -> ScriptedTraffic | SumoTraffic:
        if self.config.cars == 0:
            return ScriptedTraffic(self.track, [], [], [], seed=self.seed)
        return SumoTraffic(self.track, self.config.cars, seed=self.seed, dt=self.config.dt, ego=self.ego_pose(),
                           ego_speed=self.ego.speed, transport=self.config.sumo)

    def close(self) -> None:
        if self._traffic is not None:
            self._traffic.close()
            self._traffic = None
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def recover(self) -> None:
        """Put a lost host car back on the nearest lane centre, along the road, at no more than 10 m/s."""
        k = self.track.lane_of(self.ego.d)
        self.ego = VehicleState(s=self.ego.s, d=float(self.track.lane_centres[k]), heading=0.0,
                                speed=min(self.ego.speed, 10.0))

    # --- stepping ------------------------------------------------------------------------------------------------
    def ego_pose(self) -> np.ndarray:
        """[x, y, yaw, s, d] of the host car."""
        x, y, h = self.track.pose(self.ego.s, self.ego.d)
        return np.array([x, y, h + self.ego.heading, self.ego.s, self.ego.d])

    def _live_traffic(self) -> ScriptedTraffic | SumoTraffic:
        if self._traffic is None:
            raise RuntimeError("the highway world is closed")
        return self._traffic

    def cars(self) -> CarStates:
        return self._live_traffic().states()

    def step(self, action, render: bool | None = None) -> Observation:
        """Advance one step under `action`: an Action, or [steer, accel, brake] as the declaration orders it."""
        if not isinstance(action, Action):
            action = Action.from_array(action)
        if self._run is not None:   # the events due now, on the state the driver just saw
            self._run.before_step(self.t, self.ego, self.last_cars, self._live_traffic())
        t0 = time.perf_counter()
        self.ego = step_vehicle(self.ego, action, self.config.dt, self.track, self.config.vehicle)
        t1 = time.perf_counter()
        self._live_traffic().step(self.config.dt, self.ego_pose(), self.ego.speed)
        self.timings["physics"] += t1 - t0
        self.timings["traffic"] += time.perf_counter() - t1
        self.t += self.config.dt
        obs = self.observe(render)
        if self._run is not None:
            self._run.observe(obs, self.last_cars)
        return obs

    @property
    def condition(self) -> str:
        """The named condition this episode's frames are drawn in (its seed's draw from the configuration's mix)."""
        return pick(self.config.condition, self.seed)

    def scenario_report(self) -> dict | None:
        """A scripted scenario's events carried out and its verdict so far (None without one)."""
        return None if self._run is None else self._run.report()

    def observe(self, render: bool | None = None) -> Observation:
        t0 = time.perf_counter()
        ego = self.ego_pose()
        cars = self.last_cars = self._live_traffic().states()
        p = self.config.vehicle
        truth = ground_truth(self.track, ego, self.ego.heading, self.ego.speed, cars.poses(), cars.length,
                             cars.speed, p.length)
        collision = bool(overlaps((ego[0], ego[1], ego[2], p.length, p.width), cars.boxes()).any())
        off_road = not self.track.on_road(self.ego.d)
        lost = not self.track.on_road(self.ego.d, margin=LOST_MARGIN)
        t1 = time.perf_counter()
        self.timings["truth"] += t1 - t0
        frame = None
        if self.config.render if render is None else render:
            frame = self._render(ego, cars)
            self.timings["render"] += time.perf_counter() - t1
        return Observation(frame, truth, self.t, collision, off_road, lost)

    def _render(self, ego: np.ndarray, cars: CarStates) -> np.ndarray:
        if self._renderer is None or self._renderer_seed != self.seed:
            if self._renderer is not None:
                self._renderer.close()
            self._renderer = Renderer(self.track, self.seed, self.config.camera, self.config.renderer,
                                      self.config.mirror, self.config.side_views,
                                      condition_of(self.config.condition, self.seed))
            self._renderer_seed = self.seed
        return self._renderer.render(ego[0], ego[1], ego[2], cars)
