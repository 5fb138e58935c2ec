"""The sidewalk world: a path with its borders and obstacles, the car, the lead car of follow mode, the stereo
camera and the exact truth record, stepped together at 30 Hz (docs/sidewalk.md).

    world = SidewalkWorld(SidewalkConfig(path="park", mode="furtive", seed=3))
    obs = world.step(np.array([0.5, 0.6]))      # steer, motor in [0, 1]
    obs.frames                                  # (left, right) (h, w, 3) uint8 RGB, or (None, None)
    obs.record                                  # float64, SIDEWALK's truth order

What the generic loop (drivestudio/loop.py) needs of a world is all here: declaration, dt, observe, step,
recover, set_mode, timings, close.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from core.conditions import CONDITION_COLUMN, SEEDED, pick
from core.worlds.sidewalk import MODES, OPERATIONS, SIDEWALK, STEP
from sim.collision import overlaps
from sim.sidewalk.car import CAR, CarState, step_car
from sim.sidewalk.conditions import condition_of
from sim.sidewalk.config import SidewalkConfig
from sim.sidewalk.errors import PathError
from sim.sidewalk.layout import Layout, build_layout
from sim.sidewalk.lead import START_GAP, LeadCar
from sim.sidewalk.paths import SidewalkPath, load_path
from sim.sidewalk.stereo import StereoRenderer
from sim.sidewalk.truth import truth_record

NEUTRAL = (0.5, 0.5)    # steer straight, motor stopped
@dataclass
class Observation:
    frames: tuple                      # (left, right) uint8 RGB, or (None, None) when not rendered
    record: np.ndarray                 # the truth record, SIDEWALK's order
    t: float                           # [s] simulated time
    end: str | None = None             # why the episode cannot go on ("off the path"), or None

    @property
    def truth(self) -> dict:
        return SIDEWALK.unpack(self.record)


def check_mode(mode: str) -> str:
    if mode not in MODES:
        raise PathError(f"unknown behavioural mode {mode!r} (modes: {', '.join(MODES)})")
    return mode


def check_operation(name: str) -> str:
    if name not in OPERATIONS:
        raise PathError(f"unknown operation mode {name!r} (operation modes: {', '.join(OPERATIONS)})")
    return name


class SidewalkWorld:
    def __init__(self, config: SidewalkConfig | None = None):
        self.config = config = config or SidewalkConfig()
        check_mode(config.mode)
        self.path: SidewalkPath = config.path if isinstance(config.path, SidewalkPath) else \
            load_path(config.path, config.path_width)
        self.layout: Layout = build_layout(self.path, config.seed, config.obstacles, config.start_s)
        st = config.stereo
        self.declaration = SIDEWALK.with_camera("left", st.height, st.width).with_camera("right", st.height, st.width)
        if config.condition != SEEDED:   # a world of named conditions records each frame's
            self.declaration = self.declaration.with_column(CONDITION_COLUMN)
        self.dt = STEP
        self.seed = int(config.seed)
        self.timings = {"render": 0.0, "physics": 0.0, "truth": 0.0}
        self._renderer: StereoRenderer | None = None
        self.car = CarState(s=self.layout.start_s, speed=float(config.start_speed))
        self.command = NEUTRAL
        self.operation, self.correcting = "expert", False
        self._next_operation = "expert"
        self._label: tuple[float, float] | None = None
        self.lead: LeadCar | None = None
        self.mode = ""
        self.t = 0.0
        self._leads = 0
        self.set_mode(config.mode)

    # --- modes ---------------------------------------------------------------------------------------------------
    def set_mode(self, name: str) -> None:
        """Switch the behavioural mode now: follow brings a lead car START_GAP ahead, the others take it away."""
        check_mode(name)
        if name == self.mode:
            return
        self.mode = name
        if name == "follow":
            ahead = self.car.s + START_GAP + CAR.length
            self.lead = LeadCar(self.layout, self.seed * 1009 + self._leads, ahead,
                                max(0.0, self.car.speed))
            self._leads += 1
        else:
            self.lead = None

    def set_label(self, command) -> None:
        """The expert's command for the next step where another is applied (the perturbed expert's data,
        controller/sidewalk/perturbed.py): the record after the step carries it as its steer and motor, the label a
        data moment learns, while the car moves under the command applied (the dataset's action column)."""
        steer, motor = self.declaration.clip_action(np.asarray(command, dtype=np.float64)).tolist()
        self._label = (steer, motor)

    def set_operation(self, name: str) -> None:
        """The operation mode of the next command (the supervisor's decision): expert, autonomous or
        correctional. The record after the step carries it."""
        self._next_operation = check_operation(name)

    # --- lifecycle -----------------------------------------------------------------------------------------------
    def close(self) -> None:
        self._renderer = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    @property
    def renderer(self) -> StereoRenderer:
        if self._renderer is None:
            self._renderer = StereoRenderer(self.layout, self.seed, self.config.stereo,
                                            condition_of(self.config.condition, self.seed, self.path.style))
        return self._renderer

    @property
    def condition(self) -> str:
        """The named condition the frames are drawn in (the seed's draw from the configuration's mix)."""
        return pick(self.config.condition, self.seed)

    def recover(self) -> None:
        """Put a lost car back on the path: on the centreline (or beside an obstacle standing there), along the
        path, at rest."""
        s = self.car.s
        track = self.path.track
        for _ in range(20):
            x, y, h = track.pose(s, 0.0)
            if not overlaps((x, y, h, CAR.length + 0.2, CAR.width + 0.2), self.layout.obstacle_boxes).any():
                break
            s = track.wrap_s(s + 0.5)
        self.car = CarState(s=s, d=0.0, heading=0.0, speed=0.0)
        self.command = NEUTRAL

    # --- stepping ------------------------------------------------------------------------------------------------
    def step(self, action, render: bool | None = None) -> Observation:
        """Advance one step (33 ms) under [steer, motor] (NaN: neutral; clipped to [0, 1])."""
        steer, motor = self.declaration.clip_action(action).tolist()
        t0 = time.perf_counter()
        self.car = step_car(self.car, steer, motor, self.dt, self.path.track)
        if self.lead is not None:
            self.lead.step(self.dt)
        self.timings["physics"] += time.perf_counter() - t0
        self.command, self._label = self._label or (steer, motor), None
        self.operation = self._next_operation
        self.correcting = self.operation == "correctional"
        self.t += self.dt
        return self.observe(render)

    def observe(self, render: bool | None = None) -> Observation:
        t0 = time.perf_counter()
        lead = self.lead.state if self.lead is not None else None
        record, lost = truth_record(self.layout, self.car, lead, self.command, MODES.index(self.mode),
                                    OPERATIONS.index(self.operation), self.correcting)
        t1 = time.perf_counter()
        self.timings["truth"] += t1 - t0
        frames: tuple = (None, None)
        if self.config.render if render is None else render:
            x, y, yaw = record[SIDEWALK.index("x")], record[SIDEWALK.index("y")], record[SIDEWALK.index("yaw")]
            frames = self.renderer.render(float(x), float(y), float(yaw), lead)
            self.timings["render"] += time.perf_counter() - t1
        return Observation(frames, record, self.t, "off the path" if lost else None)
