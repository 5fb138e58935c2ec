"""Lock-step exchange between real, separate processes: a Python driver process and a Python world process (the C
driver printed in docs/shm-protocol.md: test_c_driver.py)."""
from __future__ import annotations

import sys

import numpy as np

from core.worlds.highway import HIGHWAY, Action
from shm_bridge.endpoints import DriverEndpoint, WorldEndpoint
from tests.shm_bridge.processes import spawn
from tests.shm_bridge.records import ESTIMATE_LEN, TRUTH_LEN, same

N_FRAMES = 1000


def frame_for(seq: int, h: int = 210, w: int = 280) -> np.ndarray:
    return np.full((h, w, 3), seq % 256, dtype=np.uint8)


def truth_for(seq: int) -> np.ndarray:
    return np.linspace(-1.0, 1.0, TRUTH_LEN) * seq


def estimate_for(seq: int) -> np.ndarray:
    return np.linspace(0.0, 1.0, ESTIMATE_LEN) * seq


def action_for(seq: int) -> Action:
    return Action(steer=(seq % 256) / 255.0, accel=seq * 0.1, brake=0.0)


def driver_main(name: str) -> int:
    """A driver process: every frame must come, in order, intact; answer each with action_for(seq)."""
    with DriverEndpoint(name, attach_timeout=10) as driver:
        last = 0
        while (msg := driver.wait_frame(timeout=10)) is not None:
            if msg.seq != last + 1:
                print(f"skipped from {last} to {msg.seq}", file=sys.stderr)
                return 3
            if not (msg.frame == msg.seq % 256).all() or not np.array_equal(msg.record, truth_for(msg.seq)):
                print(f"frame {msg.seq} is not the one published", file=sys.stderr)
                return 4
            if msg.t != msg.seq * 0.1:
                print(f"frame {msg.seq} has time {msg.t}", file=sys.stderr)
                return 5
            driver.send_action(msg.seq, action_for(msg.seq), estimate_for(msg.seq))
            last = msg.seq
    print(last)
    return 0


def world_main(name: str, n: str) -> int:
    """A world process: publish n frames lock-step and check every answer."""
    with WorldEndpoint(name, HIGHWAY) as world:
        world.wait_for_driver(timeout=10)
        for seq in range(1, int(n) + 1):
            assert world.publish(frame_for(seq), truth_for(seq), seq * 0.1) == seq
            act = world.wait_action(seq, timeout=10)
            if act.seq != seq or not same(act.action, action_for(seq)):
                print(f"wrong answer {act} to frame {seq}", file=sys.stderr)
                return 3
    return 0


def test_lockstep_with_a_driver_process(name):
    with WorldEndpoint(name, HIGHWAY, lockstep=True) as world:
        proc = spawn("test_lockstep", "driver_main", name)
        try:
            world.wait_for_driver(timeout=20)
            assert world.driver_pid == proc.pid
            for seq in range(1, N_FRAMES + 1):
                assert world.publish(frame_for(seq), truth_for(seq), seq * 0.1) == seq
                act = world.wait_action(seq, timeout=10)
                assert act.seq == seq and same(act.action, action_for(seq))
                np.testing.assert_array_equal(act.estimate, estimate_for(seq))
                assert world.driver_seen_seq == seq
        finally:
            world.close()
            out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    assert out.strip() == str(N_FRAMES)


def test_lockstep_with_a_world_process(name):
    proc = spawn("test_lockstep", "world_main", name, N_FRAMES)
    try:
        with DriverEndpoint(name, attach_timeout=20) as driver:
            assert driver.lockstep and driver.world == "highway"
            assert [(c.name, c.height, c.width) for c in driver.layout.cameras] == [("front", 210, 280)]
            seqs = []
            while (msg := driver.wait_frame(timeout=10)) is not None:
                assert (msg.frame == msg.seq % 256).all()
                driver.send_action(msg.seq, action_for(msg.seq))
                seqs.append(msg.seq)
        assert seqs == list(range(1, N_FRAMES + 1))
    finally:
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
