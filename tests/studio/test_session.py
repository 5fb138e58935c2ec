"""The studio's session in one process, on the real worlds: the person's take-over goes through the world's supervisor
(on the sidewalk: recorded as correctional and counted in percentage autonomy, as MultiNet's RC override), a person
driving alone records expert demonstrations, the highway's human command is applied as given, and a recording
spans resets as one dataset."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from core.worlds.sidewalk import OPERATIONS, SIDEWALK
from drivestudio import worlds
from drivestudio.studio.controls import Controls
from drivestudio.studio.human import TAKEOVER_HOLD, Keys
from drivestudio.studio.protocol import Message
from drivestudio.studio.publisher import Publisher
from drivestudio.studio.session import Restart, Session
from drivestudio.studio.watch import Watch
from perception.shards import Dataset


def session(world: str, model: str, tmp_path, **settings) -> Session:
    """A session of `world` whose configuration has the given settings (obstacles as the command line's text)."""
    plugin = worlds.get(world)
    config = plugin.config_type()
    if "obstacles" in settings:
        from sim.sidewalk.config import obstacles_value
        settings["obstacles"] = obstacles_value(settings["obstacles"])
    config = replace(config, **settings)
    s = Session(plugin, config, tmp_path, {}, Watch(Publisher(), None), Controls(realtime=False), shard_steps=40,
                model=model)
    s.open()
    return s


def press(s: Session, keys: Keys, steps: range) -> list[bool]:
    """Hold `keys` during the given steps of the run; returns, per step, whether the person drove it."""
    drove: list[bool] = []
    step = s.on_step

    def on_step(rec) -> None:
        drove.append(s._mode == "human")
        step(rec)
        s.human.set(keys if s.watch.rate.steps in steps else Keys(), None)
    s.on_step = on_step     # type: ignore[method-assign]
    return drove


def test_a_person_taking_over_a_network_is_recorded_as_correctional_and_counted_in_autonomy(tmp_path):
    s = session("sidewalk", "poor", tmp_path, operation="autonomous", obstacles="none")
    s.handle(Message("record", {"on": True, "name": "takeover"}))
    drove = press(s, Keys(up=True), range(30, 60))
    s.run(seconds=4.0)                                       # 120 steps
    report = s.metrics.report()
    human = int(sum(drove))
    assert human == 30 + round(TAKEOVER_HOLD * 30) - 1      # the touch, and the hold after it (0.5 s)
    assert report["corrections"] == 1
    assert report["autonomy_percent"] == pytest.approx((1 - human / 120) * 100, abs=0.01)
    data = Dataset(tmp_path / "recordings" / "takeover")
    ops = data.labels(columns=["operation", "correcting"])
    # the record of a step carries the operation of the command applied on the step before
    taken = np.flatnonzero(ops["operation"] == OPERATIONS.index("correctional"))
    assert len(taken) == human and ops["correcting"][taken].all()
    rest = ops["operation"][1:]                  # the first record precedes any command: the world's initial state
    assert set(rest[rest != 2]) == {OPERATIONS.index("autonomous")}
    assert sum(s_.params["human_steps"] for s_ in data.shards) == human


def test_a_person_driving_alone_records_expert_demonstrations_of_their_own_commands(tmp_path):
    s = session("sidewalk", "human", tmp_path, obstacles="none")
    s.handle(Message("record", {"on": True, "name": "demo"}))
    press(s, Keys(up=True, right=True), range(0, 10))
    s.run(seconds=1.0)
    data = Dataset(tmp_path / "recordings" / "demo")
    labels = data.labels(columns=["operation", "steer", "motor", "action"])
    assert set(labels["operation"]) == {OPERATIONS.index("expert")}
    actions = np.array([list(a) for a in labels["action"]], dtype=np.float64)
    assert actions[9, 0] > 0.5 and actions[9, 1] > 0.5             # right and forward, as pressed
    np.testing.assert_allclose(labels["steer"][1:], actions[:-1, 0], atol=1e-6)   # what the car was under
    np.testing.assert_allclose(labels["motor"][1:], actions[:-1, 1], atol=1e-6)
    assert s.metrics.report()["autonomy_percent"] == 100.0


def test_the_highway_applies_the_persons_command_over_the_oracle(tmp_path):
    s = session("highway", "oracle", tmp_path, cars=0)
    applied: list[np.ndarray] = []
    step = s.on_step

    def on_step(rec) -> None:
        applied.append(np.asarray(rec.action))
        step(rec)
    s.on_step = on_step     # type: ignore[method-assign]
    drove = press(s, Keys(left=True), range(5, 15))
    s.run(seconds=2.0)
    human = [i for i, d in enumerate(drove) if d]
    # pressed 10 steps; the take-over ends 0.5 s after the last step the keys were held
    assert human[0] == 5 and len(human) == 10 + round(TAKEOVER_HOLD / 0.1) - 1
    assert all(applied[i][0] > 0 for i in human[:10])               # steering left is positive on the highway
    assert all(applied[i][0] >= 0 for i in human[10:])              # ramping back while still held
    assert all(abs(applied[i][0]) < 0.05 for i in range(5))         # the oracle keeps its lane


def test_a_recording_goes_on_across_a_reset_as_new_episodes(tmp_path):
    s = session("sidewalk", "expert", tmp_path, obstacles="none")
    s.handle(Message("record", {"on": True, "name": "across"}))
    n = {"resets": 0}
    step = s.on_step

    def on_step(rec) -> None:
        step(rec)
        if s.watch.rate.steps == 25 and n["resets"] == 0:
            n["resets"] += 1
            raise Restart({"seed": 7, "path": "forest"})
    s.on_step = on_step     # type: ignore[method-assign]
    s.run(seconds=1.0)
    data = Dataset(tmp_path / "recordings" / "across")
    assert [sh.frames for sh in data.shards] == [25, 30]
    assert data.shards[0].params["path"] == "park" and data.shards[1].params == {
        "path": "forest", "seed": 7, "drivers": ["expert"], "human_steps": 0}
    assert data.declaration == SIDEWALK


def test_a_reset_that_cannot_be_built_is_refused_and_the_scene_goes_on(tmp_path):
    told = []
    s = session("sidewalk", "expert", tmp_path, obstacles="none")
    s.tell = lambda kind, **f: told.append((kind, f))
    s._reset({"path": "procedural:1", "path_width": 99.0})     # a width no path may have
    assert any(kind == "error" and "reset refused" in f["message"] for kind, f in told)
    assert s.world is not None and s.config.path == "park" and s.config.path_width is None   # the one before


def _lateral_after(tmp_path, tap_steps: int, seconds: float) -> tuple[list[float], list[float], float]:
    """The highway at 20 m/s, nobody else on it, the person's right arrow held for the first `tap_steps` steps;
    returns the car's lateral offset d [m] (+ left) and speed at every step, and the lane width."""
    s = session("highway", "human", tmp_path, cars=0, start_speed=20.0)
    d: list[float] = []
    speed: list[float] = []
    step = s.on_step

    def on_step(rec) -> None:
        d.append(float(rec.obs.truth.ego[4]))
        speed.append(float(rec.obs.truth.speed))
        step(rec)
    s.on_step = on_step     # type: ignore[method-assign]
    if tap_steps:
        s.human.set(Keys(right=True), None)
        press(s, Keys(right=True), range(1, tap_steps))
    width = float(s.world.track.lane_width)
    s.run(seconds=seconds)
    return d, speed, width


def test_a_tap_at_highway_speed_moves_the_car_well_under_a_lane(tmp_path):
    """A 0.6 s tap of an arrow at 20 m/s, then hands off for a second: the car is nudged toward the next lane, not
    sent across it (the steering's ramp and limit fall with speed, drivestudio/studio/kit.py)."""
    tap, seconds = 6, 1.7          # 6 steps of 0.1 s; the offset at 1.6 s, a second after letting go
    base, speed, width = _lateral_after(tmp_path / "base", 0, seconds)
    tapped, _, _ = _lateral_after(tmp_path / "tap", tap, seconds)
    assert speed[0] == pytest.approx(20.0, abs=0.5)
    moved = base[-1] - tapped[-1]      # toward the right: d falls
    assert 0.05 < moved < width / 4, (moved, width)


def test_a_recording_stopped_just_after_an_episode_ends_writes_no_one_step_episode(tmp_path):
    told = []
    s = session("sidewalk", "expert", tmp_path, obstacles="none")        # 40-step episodes
    s.tell = lambda kind, **f: told.append((kind, f))
    s.handle(Message("record", {"on": True, "name": "tail"}))
    step = s.on_step

    def on_step(rec) -> None:
        step(rec)
        if s.recorder is not None and s.recorder.steps == 41:            # one step into the second episode
            s.handle(Message("record", {"on": False}))
    s.on_step = on_step     # type: ignore[method-assign]
    s.run(seconds=2.0)
    data = Dataset(tmp_path / "recordings" / "tail")
    assert [sh.frames for sh in data.shards] == [40] and data.manifest["complete"]
    done = [f["message"] for kind, f in told if kind == "info" and "recording_done" in f]
    assert done and "recorded 40 steps in 1 shard(s)" in done[0] and "1 step(s) left out" in done[0]
