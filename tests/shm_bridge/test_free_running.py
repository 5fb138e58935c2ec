"""Free-running mode between real processes: the world never waits, the driver always takes the newest frame,
and no frame the driver takes is torn (every pixel of frame seq equals seq % 256, its truth matches seq)."""
from __future__ import annotations

import json
import time

import numpy as np

from core.worlds.highway import HIGHWAY, Action
from shm_bridge.endpoints import DriverEndpoint, WorldEndpoint
from tests.shm_bridge.processes import spawn
from tests.shm_bridge.records import TRUTH_LEN, same, small


def truth_for(seq: int) -> np.ndarray:
    return np.full(TRUTH_LEN, float(seq))


def action_for(seq: int) -> Action:
    return Action(steer=(seq % 256) / 255.0, accel=float(seq), brake=0.5)


def driver_main(name: str, pause: str) -> int:
    """Take frames until the world closes; check each one is whole; report what was seen as JSON."""
    torn = taken = 0
    last = 0
    increasing = True
    with DriverEndpoint(name, attach_timeout=10) as driver:
        if driver.lockstep:
            return 5
        while (msg := driver.wait_frame(timeout=10)) is not None:
            taken += 1
            increasing &= msg.seq > last
            last = msg.seq
            lo, hi = int(msg.frame.min()), int(msg.frame.max())
            if lo != hi or lo != msg.seq % 256 or not np.array_equal(msg.record, truth_for(msg.seq)):
                torn += 1
            driver.send_action(msg.seq, action_for(msg.seq))
            if float(pause) > 0:
                time.sleep(float(pause))   # a slow network: the world must not wait for it
        discarded = driver.discarded_copies   # copies the seqlock rejected (the world rewrote the slot meanwhile)
    print(json.dumps({"taken": taken, "torn": torn, "last": last, "increasing": increasing, "discarded": discarded}))
    return 0


def _run_world(name: str, duration: float, driver_pause: float) -> tuple[dict, int, list]:
    frame = np.empty((210, 280, 3), dtype=np.uint8)
    answers = []
    with WorldEndpoint(name, HIGHWAY, lockstep=False) as world:
        proc = spawn("test_free_running", "driver_main", name, driver_pause)
        try:
            world.wait_for_driver(timeout=20)
            end = time.monotonic() + duration
            seq = 0
            while time.monotonic() < end:
                frame.fill((seq + 1) % 256)
                seq = world.publish(frame, truth_for(seq + 1))
                act = world.latest_action()      # never waits
                if act is not None:
                    answers.append(act)
        finally:
            world.close()
            out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    return json.loads(out), seq, answers


def test_free_running_frames_are_never_torn(name):
    stats, published, answers = _run_world(name, duration=1.5, driver_pause=0.0)
    assert stats["torn"] == 0
    assert stats["taken"] > 100 and stats["increasing"]
    assert published > stats["taken"]            # the world ran ahead and the driver skipped frames
    for act in answers:                           # every action read whole, and for a frame that existed
        assert 1 <= act.seq <= published and same(act.action, action_for(act.seq))
    assert [a.seq for a in answers] == sorted(a.seq for a in answers)


def test_free_running_world_does_not_wait_for_a_slow_driver(name):
    stats, published, answers = _run_world(name, duration=1.0, driver_pause=0.05)
    assert stats["torn"] == 0 and stats["increasing"]
    assert stats["taken"] <= 25                   # 1 s at 50 ms per frame
    assert published > 20 * stats["taken"]
    assert answers and answers[-1].seq <= stats["last"]


def test_free_running_in_one_process_takes_the_newest_frame(name):
    with WorldEndpoint(name, small(3, 4), lockstep=False) as world, DriverEndpoint(name) as driver:
        for seq in range(1, 6):
            world.publish(np.full((3, 4, 3), seq, np.uint8), truth_for(seq))
        msg = driver.wait_frame(timeout=1)
        assert msg.seq == 5 and (msg.frame == 5).all()
        assert world.latest_action() is None
        driver.send_action(5, action_for(5))
        driver.send_action(4, action_for(4))    # the newest action is the last one stored, whatever its seq
        assert world.latest_action().seq == 4
