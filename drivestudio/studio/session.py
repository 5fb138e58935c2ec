"""The studio's run: the world of a configuration, the driver the page chooses (the world's own, a checkpoint, or
the person at the controls), the world's supervisor and metrics, and a recording when asked.

The studio is the loop's third consumer, not a second loop: drivestudio/loop.py's run_loop steps the world, with
`exchange` as its transport and `on_step` as its step callback. The exchange paces the loop (real time or as fast
as it can), asks the driver, and lets the person take over: whenever they touch the controls while another driver
drives, their command goes through the world's supervisor as driver mode "human" (on the sidewalk: recorded as a
correction, counted in percentage autonomy, as MultiNet's RC override). on_step records, publishes and obeys the
pages' messages (pause, step, driver, mode, reset, record); a reset ends run_loop with `Restart` and a new world is
built. Only this thread touches the world; the server's thread queues messages (drivestudio/studio/controls.py).
"""
from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from core.settings import check, with_values
from drivestudio.driver_spec import DriverSpec
from drivestudio.loop import Observation, StepRecord, run_loop
from drivestudio.studio.controls import Controls, Pacer
from drivestudio.studio.human import TAKEOVER_HOLD, HumanDriver, HumanInput, Keys, Pad
from drivestudio.studio.protocol import Message
from drivestudio.studio.recording import DEFAULT_SHARD_STEPS, MIN_EPISODE_STEPS, DatasetRecorder
from drivestudio.studio.watch import Watch

HUMAN = "human"


class Restart(Exception):
    """A page asked for a new scene (seed, track or path): run_loop ends and the session builds it."""

    def __init__(self, changes: dict):
        super().__init__("reset")
        self.changes = changes


class Session:
    def __init__(self, plugin, config, out: Path, checkpoints: dict[str, str], watch: Watch, controls: Controls,
                 tell=lambda kind, **fields: None, shard_steps: int = DEFAULT_SHARD_STEPS, model: str | None = None,
                 device: str = "cpu"):
        """`config`: the world's configuration (a reset changes its scene and seed); `model`: who drives at the
        start (default: the person)."""
        self.plugin, self.config, self.out, self.device = plugin, config, out, device
        self.checkpoints, self.watch, self.controls, self.tell = checkpoints, watch, controls, tell
        self.shard_steps = shard_steps
        self.kit = plugin.studio()
        self.scene_key = self.kit.scene_key         # the highway's tracks, the sidewalk's paths
        self.drivers = [HUMAN] + list(plugin.expert_names) + list(checkpoints)
        self.driver_name = model or HUMAN
        self.spec = DriverSpec(self.driver_name)
        self.operation = getattr(config, "operation", None)
        self.human = HumanInput()
        self.world: Any = None           # the world of the configuration (a reset builds a new one)
        self.driver: Any = None          # a Driver of drivestudio/loop.py
        self.human_driver: Any = None    # the person, always there for take-overs
        self.supervisor: Any = None
        self.metrics: Any = None
        self.recorder: DatasetRecorder | None = None
        self.pacer = Pacer(plugin.declaration.dt)
        self._realtime = controls.realtime
        self._mode = "network"           # who drove the last step: "human" or "network"

    # --- what the pages are offered ----------------------------------------------------------------------------
    def scenes(self) -> list[str]:
        return self.kit.presets()

    def hello(self) -> dict:
        decl = self.plugin.declaration
        return {"world": decl.name, "title": decl.title, "dt": decl.dt, "studio": True,
                "cameras": [c.name for c in decl.cameras],
                "action": [{"name": a.name, "low": a.low, "high": a.high, "neutral": a.neutral} for a in decl.action],
                "drivers": self.drivers, "modes": list(decl.modes),
                "operations": ["expert", "autonomous", "correctional"] if decl.modes else [],
                "scene_key": self.scene_key, "scenes": self.scenes(), "out": str(self.out),
                "labels_note": self.kit.note, "takeover_hold": TAKEOVER_HOLD}

    # --- the run -----------------------------------------------------------------------------------------------
    def open(self) -> None:
        """Build the first world and its driver: a configuration that cannot make them fails here, before the
        server starts."""
        self.world = self.plugin.world(replace(self.config, render=True))
        self._use_driver(self.driver_name)

    def run(self, seconds: float = math.inf) -> None:
        """Drive until interrupted (Ctrl-C, SIGTERM), or for `seconds` of simulated time of one scene; a recording
        in progress is completed."""
        try:
            while True:
                try:
                    self._drive(seconds)
                    return
                except Restart as r:
                    self._reset(r.changes)
        finally:
            self._stop_recording()
            if self.world is not None:
                self.world.close()

    def _drive(self, seconds: float) -> None:
        world = self.world
        self.metrics = self.plugin.metrics(world)
        self.watch.restart(self.kit.view_for(world, self.config), self.metrics)
        self.pacer.restart()
        self.tell("info", message=f"{world.declaration.name}: " + ", ".join(f"{k} {v}" for k, v in
                                                                             self._scene().items()))
        run_loop(world, self.exchange, seconds, render=True, metrics=self.metrics, on_step=self.on_step,
                 when_lost="recover")

    def _scene(self) -> dict:
        return self.kit.scene(self.config)

    def _reset(self, changes: dict) -> None:
        """A new world for the changed settings; if it cannot be built, the one before is built again."""
        if self.recorder is not None:
            self.recorder.cut()      # a new scene is a new episode
        self.world.close()
        self.world = None
        before = self.config
        try:
            self.config = check(with_values(self.config, changes))
            self.world = self.plugin.world(replace(self.config, render=True))
        except Exception as e:       # noqa: BLE001 - any failure to build is the page's to hear, not the end
            self.config = before
            self.tell("error", message=f"reset refused: {_line(e)}", about="reset")
            self.world = self.plugin.world(replace(self.config, render=True))
        self._use_driver(self.driver_name)     # drivers keep state of the world they drove (lanes, history)

    # --- the transport -----------------------------------------------------------------------------------------
    def exchange(self, obs: Observation) -> tuple[np.ndarray, np.ndarray]:
        if self.controls.realtime != self._realtime:
            self._realtime = self.controls.realtime
            self.pacer.restart()
        if self._realtime:
            self.pacer.wait()      # before acting, so that the newest input is read when the step is due
        human_action, no_estimate = self.human_driver.act(obs)   # the inputs advance once per step
        if self.driver is self.human_driver:
            action, estimate, mode = human_action, no_estimate, "human"
        else:
            action, estimate = self.driver.act(obs)
            mode = "human" if self.human.touching else "network"
            if mode == "human":
                action = human_action
        if self.supervisor is not None:
            action, _ = self.supervisor(obs, action, mode)
        self._mode = mode
        return action, estimate

    def on_step(self, rec: StepRecord) -> None:
        who = HUMAN if self._mode == "human" else self.driver_name
        if self.recorder is not None:
            self.recorder.add(rec, self.watch.view.columns(rec, "human" if who == HUMAN else "none"),
                              {**self._scene(), "drivers": [who], "human_steps": int(who == HUMAN)},
                              int(self.config.seed))
        self.watch.step(rec, self.driver, self.supervisor, self._extra(), self.driver_name)
        if self.controls.hold(self.handle, idle=self._idle):
            self.pacer.restart()
            self.watch.rate.restart()     # a pause is not the loop falling behind

    def _idle(self) -> None:
        if self.watch.republish(self.driver, self.supervisor, self._extra(), self.driver_name, self.controls.changed):
            self.controls.changed = False

    def _extra(self) -> dict:
        rec = self.recorder
        return {"driver": self.driver_name, "human": self._mode == "human", "paused": self.controls.paused,
                "realtime": self.controls.realtime, "scene": self._scene(),
                "takeover": self._mode == "human" and self.driver is not self.human_driver,
                "input": [round(self.human.steer, 3), round(self.human.throttle, 3), round(self.human.brake, 3)],
                "recording": None if rec is None else {"name": rec.root.name, "path": str(rec.root),
                                                       "steps": rec.steps, "shards": rec.shards}}

    # --- drivers -----------------------------------------------------------------------------------------------
    def _use_driver(self, name: str) -> None:
        """Make the driver `name` for the present world (a checkpoint is loaded here); the human's driver is always
        there, for take-overs."""
        decl = self.world.declaration
        self.human_driver = HumanDriver(self.kit.human, decl.dt, len(decl.estimate_names), decl.index("speed"),
                                        self.human)
        if name == HUMAN:
            driver, spec = self.human_driver, DriverSpec(HUMAN)
        else:
            spec = self.plugin.parse_driver(self.checkpoints.get(name, name))
            driver = self.plugin.driver(spec, self.device, decl, self.config.seed)
        self.driver, self.driver_name, self.spec = driver, name, spec
        self._supervise()

    def _supervise(self) -> None:
        """The world's supervisor for the driver. On the sidewalk a person drives as the expert (a demonstration);
        another driver under the operation the page chose, or drive's default (expert for the world's expert,
        correctional otherwise)."""
        config = self.config
        if self.plugin.declaration.modes:
            config = replace(config, operation="expert" if self.driver_name == HUMAN else self.operation)
        self.supervisor = self.plugin.supervisor(self.world, config, self.spec)

    def _switch_driver(self, name: str) -> None:
        previous = self.driver_name
        self.tell("info", message=f"loading {name} ..." if name in self.checkpoints else f"{name} drives")
        try:
            self._use_driver(name)
        except Exception as e:   # noqa: BLE001 - a checkpoint that cannot drive is the page's to hear
            self._use_driver(previous)
            self.tell("error", message=f"{name} cannot drive: {_line(e)}", about="driver")
            return
        if name in self.checkpoints:
            self.tell("info", message=f"{name} drives")

    # --- messages (the loop's thread) --------------------------------------------------------------------------
    def handle(self, msg: Message) -> None:
        f = msg.fields
        if msg.type == "driver":
            self._switch_driver(f["name"])
        elif msg.type == "mode":
            self.world.set_mode(f["mode"])
            self.config = replace(self.config, mode=f["mode"])        # and a reset keeps it
        elif msg.type == "operation":
            self.operation = f["operation"]
            self._supervise()
        elif msg.type == "reset":
            raise Restart(f)
        elif msg.type == "record":
            self._start_recording(f.get("name")) if f["on"] else self._stop_recording()

    def _start_recording(self, name: str | None) -> None:
        if self.recorder is not None:
            return
        from drivestudio.generate import _software  # lazy: tqdm
        name = name or time.strftime("rec-%Y%m%d-%H%M%S")
        decl = self.world.declaration
        meta = {"config": {"world": decl.name, "studio": {**self._scene(), **self.plugin.describe_run(
                    self.world, self.config, self.spec)}},
                "seed": int(self.config.seed), "renderer": getattr(self.config, "renderer", "painter"),
                "recorded_by": "drivestudio studio", "software": _software()}
        try:
            self.recorder = DatasetRecorder(self.out / "recordings" / name, decl, meta, self.shard_steps)
        except Exception as e:   # noqa: BLE001 - a name in use, a full disk: the page hears it
            self.tell("error", message=f"cannot record: {_line(e)}", about="record")
            return
        self.tell("info", message=f"recording to {self.recorder.root}")

    def _stop_recording(self) -> None:
        if self.recorder is None:
            return
        rec, self.recorder = self.recorder, None
        manifest = rec.close()
        line = f"recorded {manifest['frames']} steps in {len(manifest['shards'])} shard(s) at {rec.root}"
        if rec.left_out:
            line += f" ({rec.left_out} step(s) left out, in episodes of fewer than {MIN_EPISODE_STEPS} steps)"
        print(line, flush=True)
        self.tell("info", message=line, recording_done=str(rec.root))

    # --- the server's thread -----------------------------------------------------------------------------------
    def submit(self, msg: Message, client) -> str | None:
        """Check a page's message against what is offered and queue it for the loop; input goes straight to the
        person's controls. Returns an error line, or None."""
        f = msg.fields
        if msg.type == "input":
            pad = f.get("gamepad")
            self.human.set(Keys(**f["keys"]), None if pad is None else Pad(**pad))
            return None
        if msg.type == "driver" and f["name"] not in self.drivers:
            return f"no driver {f['name']!r} here (drivers: {', '.join(self.drivers)})"
        decl = self.plugin.declaration
        if msg.type == "mode" and f["mode"] not in decl.modes:
            return f"no behavioural mode {f['mode']!r} in the {decl.name} world" + (
                f" (modes: {', '.join(decl.modes)})" if decl.modes else "")
        if msg.type == "operation" and (not decl.modes or f["operation"] not in ("expert", "autonomous",
                                                                                  "correctional")):
            return f"no operation mode {f['operation']!r} in the {decl.name} world"
        if msg.type == "reset":
            other = "track" if self.scene_key == "path" else "path"
            if other in f:
                return f"the {decl.name} world has a {self.scene_key}, not a {other}"
            scene = f.get(self.scene_key)
            if scene is not None and scene not in self.scenes() and not scene.startswith("procedural:"):
                return f"no {self.scene_key} {scene!r} here ({', '.join(self.scenes())} or procedural:SEED)"
        self.controls.put(msg)
        return None

    def wheel_left(self, client=None) -> None:
        """The page holding the wheel went away: nothing is held, and a recording is completed (nothing lost)."""
        self.human.release()
        self.controls.put(Message("record", {"on": False}))


def _line(e: BaseException) -> str:
    text = str(e).strip().splitlines()
    return text[0] if text else type(e).__name__
