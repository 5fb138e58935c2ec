"""Creating, attaching, refusing and removing segments (both endpoints in this process where no second process
is needed; the exchanges between real processes are in test_lockstep, test_free_running and test_shutdown)."""
from __future__ import annotations

import gc
import os
import stat
import subprocess
import sys
import time

import numpy as np
import pytest

from shm_bridge import layout
from shm_bridge.endpoints import (ActionMsg, BridgeError, BridgeTimeout, DriverEndpoint, PeerGone, ProtocolMismatch,
                                  WorldEndpoint)
from shm_bridge.worlds.highway import Action


def _frame(value: int, h: int = 210, w: int = 280) -> np.ndarray:
    return np.full((h, w, 3), value, dtype=np.uint8)


def _truth(seq: int) -> np.ndarray:
    t = np.arange(layout.TRUTH_LEN, dtype=np.float64)
    t[layout.TRUTH_INDEX["t"]] = seq * 0.1
    return t


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_segment_is_private_and_removed_after_close(name):
    path = f"/dev/shm/{name}"
    world = WorldEndpoint(name)
    st = os.stat(path)
    assert stat.S_IMODE(st.st_mode) == 0o600
    assert st.st_size == layout.layout_size(210, 280)
    world.close()
    assert not os.path.exists(path)
    world.close()  # twice is fine
    with pytest.raises(BridgeError, match="closed"):
        world.publish(_frame(0), _truth(1))


def test_handshake_and_header(name):
    with WorldEndpoint(name, height=60, width=80, lockstep=False) as world:
        with pytest.raises(BridgeTimeout, match="no driver attached"):
            world.wait_for_driver(timeout=0.05)
        assert not world.driver_attached
        with DriverEndpoint(name, attach_timeout=1) as driver:
            world.wait_for_driver(timeout=1)
            assert world.driver_attached and world.driver_pid == os.getpid()
            assert (driver.height, driver.width, driver.channels, driver.lockstep) == (60, 80, 3, False)
            assert driver.world_pid == os.getpid()
            assert world.latest_action() is None
            seq = world.publish(_frame(7, 60, 80), _truth(1))
            msg = driver.wait_frame(timeout=1)
            assert msg.seq == seq == 1 and msg.frame.shape == (60, 80, 3) and (msg.frame == 7).all()
            np.testing.assert_array_equal(msg.truth, _truth(1))
            assert msg.t == pytest.approx(0.1) and world.driver_seen_seq == 1
            with pytest.raises(BridgeTimeout, match="no frame"):
                driver.wait_frame(timeout=0.05)
            est = np.linspace(0, 1, 14)
            driver.send_action(msg.seq, Action(0.25, 0.5, 0.0), est)
            act = world.latest_action()
            assert isinstance(act, ActionMsg) and act.seq == 1 and act.action == Action(0.25, 0.5, 0.0)
            np.testing.assert_array_equal(act.estimate, est)
            driver.send_action(msg.seq, [0.0, 0.0, 1.0])
            assert not world.wait_action(1, timeout=1).has_estimate


def test_frames_are_copies_and_mapping_is_refused(name):
    with WorldEndpoint(name, height=4, width=5) as world, DriverEndpoint(name) as driver:
        world.publish(_frame(1, 4, 5), layout.pack_truth({n: 1.0 for n in layout.TRUTH_FIELDS}))
        msg = driver.wait_frame(timeout=1)
        world.publish(_frame(2, 4, 5), _truth(2))
        world.publish(_frame(3, 4, 5), _truth(3))   # overwrites the slot of frame 1
        assert (msg.frame == 1).all() and (msg.truth == 1).all()
        assert driver.wait_frame(timeout=1).seq == 3   # the newest frame
        with pytest.raises(ValueError, match=r"\(4, 5, 3\) uint8"):
            world.publish(np.zeros((4, 5, 3), np.float32), _truth(4))
        with pytest.raises(ValueError, match="truth record"):
            world.publish(_frame(0, 4, 5), np.zeros(5))
        with pytest.raises(ValueError, match="14 indicators"):
            driver.send_action(3, Action(), np.zeros(13))


def test_pause_and_driver_mode_are_shared(name):
    with WorldEndpoint(name, height=2, width=2) as world, DriverEndpoint(name) as driver:
        assert not world.paused and world.driver_mode == "network"
        driver.paused = True
        assert world.paused
        world.driver_mode = "manual"
        assert driver.driver_mode == "manual"
        world.publish(_frame(0, 2, 2), _truth(1))
        msg = driver.wait_frame(timeout=1)
        assert msg.paused and msg.driver_mode == "manual"
        world.paused = False
        driver.driver_mode = 0
        assert not driver.paused and world.driver_mode == "network"
        with pytest.raises(ValueError, match="driver_mode"):
            world.driver_mode = "autopilot"


def test_world_close_ends_the_driver_in_order(name):
    world = WorldEndpoint(name, height=2, width=2)
    with DriverEndpoint(name) as driver:
        world.publish(_frame(0, 2, 2), _truth(1))
        world.close()
        assert driver.wait_frame(timeout=1).seq == 1   # frames published before the close still arrive
        assert driver.wait_frame(timeout=1) is None
        driver.send_action(1, Action())                # goes nowhere, raises nothing
    assert not os.path.exists(f"/dev/shm/{name}")


def test_driver_detach_is_reported_to_the_world(name):
    with WorldEndpoint(name, height=2, width=2) as world:
        with DriverEndpoint(name):
            world.wait_for_driver(timeout=1)
            seq = world.publish(_frame(0, 2, 2), _truth(1))
        with pytest.raises(PeerGone, match=rf"the driver \(pid {os.getpid()}\) closed the connection") as e:
            world.wait_action(seq, timeout=1)
        assert e.value.orderly and e.value.pid == os.getpid()
        assert not os.path.exists(f"/dev/shm/{name}")   # the run is over: the segment is gone already
        with pytest.raises(PeerGone):
            world.publish(_frame(0, 2, 2), _truth(2))


def test_garbage_collection_removes_the_segment(name):
    world = WorldEndpoint(name, height=2, width=2)
    driver = DriverEndpoint(name)
    del world
    gc.collect()
    assert not os.path.exists(f"/dev/shm/{name}")
    assert driver.wait_frame(timeout=1) is None
    del driver
    gc.collect()


def test_attach_to_a_missing_name_times_out(name):
    t0 = time.monotonic()
    with pytest.raises(BridgeTimeout, match=rf"no world serves shared memory '{name}' \(waited 0.2 s"):
        DriverEndpoint(name, attach_timeout=0.2)
    assert time.monotonic() - t0 < 1.0


def test_attach_waits_for_a_world_that_comes_later(name):
    code = ("import sys, time; from shm_bridge.endpoints import WorldEndpoint; time.sleep(0.3)\n"
            "with WorldEndpoint(sys.argv[1], height=2, width=2) as w:\n"
            "    w.wait_for_driver(5); w.publish(__import__('numpy').zeros((2, 2, 3), 'u1'), [0.0] * 28)\n"
            "    w.wait_action(1, 5)\n")
    proc = subprocess.Popen([sys.executable, "-c", code, name])
    try:
        with DriverEndpoint(name, attach_timeout=10) as driver:
            msg = driver.wait_frame(timeout=5)
            driver.send_action(msg.seq, Action())
            assert driver.wait_frame(timeout=5) is None
        assert proc.wait(timeout=5) == 0
    finally:
        proc.kill()
        proc.wait()


def test_version_mismatch_is_refused(name):
    with WorldEndpoint(name, height=2, width=2) as world:
        world._u32[layout.OFFSET["version"] // 4] = 3
        with pytest.raises(ProtocolMismatch, match=f"shared memory '{name}' has protocol version 3, "
                                                   "this driver speaks 1"):
            DriverEndpoint(name, attach_timeout=1)
        world._u32[layout.OFFSET["version"] // 4] = 1
        world._u64[layout.OFFSET["layout_size"] // 8] += 64
        with pytest.raises(ProtocolMismatch, match="declares a layout of"):
            DriverEndpoint(name, attach_timeout=1)
        world._u64[layout.OFFSET["layout_size"] // 8] -= 64
        with DriverEndpoint(name, attach_timeout=1):
            pass


def test_foreign_file_is_refused_and_left_alone(name):
    path = f"/dev/shm/{name}"
    with open(path, "wb") as f:
        f.write(b"NOTOURS!" + bytes(1024))
    try:
        with pytest.raises(ProtocolMismatch, match="not a drivestudio bridge segment"):
            DriverEndpoint(name, attach_timeout=1)
        with pytest.raises(BridgeError, match="already exists and is not a version-1 bridge segment"):
            WorldEndpoint(name)
        assert os.path.exists(path)
    finally:
        os.unlink(path)


def test_name_of_a_live_world_is_refused(name):
    with WorldEndpoint(name, height=2, width=2):
        with pytest.raises(BridgeError, match=rf"in use by another world process \(pid {os.getpid()}\)"):
            WorldEndpoint(name, height=2, width=2)


def test_leftover_of_a_dead_world_is_replaced(name):
    old = WorldEndpoint(name, height=2, width=2)
    old._i32[layout.OFFSET["world_pid"] // 4] = _dead_pid()   # as if its process had been killed
    ino = os.stat(f"/dev/shm/{name}").st_ino
    with WorldEndpoint(name, height=2, width=2) as new:
        assert os.stat(f"/dev/shm/{name}").st_ino != ino
        old.close()                                       # must not remove the new world's segment
        assert os.path.exists(f"/dev/shm/{name}")
        with DriverEndpoint(name, attach_timeout=1) as driver:
            assert driver.world_pid == os.getpid()
            new.publish(_frame(0, 2, 2), _truth(1))
            assert driver.wait_frame(timeout=1).seq == 1


def test_driver_removes_a_leftover_and_waits_for_a_new_world(name):
    old = WorldEndpoint(name, height=2, width=2)
    old._i32[layout.OFFSET["world_pid"] // 4] = _dead_pid()
    with pytest.raises(BridgeTimeout):
        DriverEndpoint(name, attach_timeout=0.2)
    assert not os.path.exists(f"/dev/shm/{name}")
    old.close()


def test_second_driver_is_refused(name):
    with WorldEndpoint(name, height=2, width=2), DriverEndpoint(name):
        code = "import sys; from shm_bridge.endpoints import DriverEndpoint; DriverEndpoint(sys.argv[1], 1)"
        r = subprocess.run([sys.executable, "-c", code, name], capture_output=True, text=True, timeout=20)
        assert r.returncode != 0
        assert f"shared memory '{name}' already has a driver (pid {os.getpid()})" in r.stderr


@pytest.mark.parametrize("bad", ["", "a/b", "../x", ".hidden", "x" * 201, "sp ace"])
def test_bad_names_are_refused(bad):
    with pytest.raises(BridgeError, match="bad shared-memory name"):
        WorldEndpoint(bad)


def test_forked_child_does_not_end_the_parents_run(name):
    with WorldEndpoint(name, height=2, width=2) as world:
        pid = os.fork()
        if pid == 0:   # the child: what its interpreter exit would do with the inherited endpoint
            try:
                world._finalizer()
            finally:
                os._exit(0)
        os.waitpid(pid, 0)
        assert os.path.exists(f"/dev/shm/{name}")
        with DriverEndpoint(name, attach_timeout=1) as driver:
            world.publish(_frame(0, 2, 2), _truth(1))
            assert driver.wait_frame(timeout=1).seq == 1
