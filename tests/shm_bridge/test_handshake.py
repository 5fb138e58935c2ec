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

from core.worlds.highway import HIGHWAY, Action
from shm_bridge import layout
from shm_bridge.endpoints import (
    ActionMsg,
    BridgeError,
    BridgeTimeout,
    DriverEndpoint,
    PeerGone,
    ProtocolMismatch,
    WorldEndpoint,
)
from tests.shm_bridge.processes import REPO
from tests.shm_bridge.records import ESTIMATE_LEN, TRUTH_LEN, same, small


def _frame(value: int, h: int = 210, w: int = 280) -> np.ndarray:
    return np.full((h, w, 3), value, dtype=np.uint8)


def _truth(seq: int) -> np.ndarray:
    return np.arange(TRUTH_LEN, dtype=np.float64) + seq


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_segment_is_private_and_removed_after_close(name):
    path = f"/dev/shm/{name}"
    world = WorldEndpoint(name, HIGHWAY)
    st = os.stat(path)
    assert stat.S_IMODE(st.st_mode) == 0o600
    assert st.st_size == layout.layout_for(HIGHWAY).layout_size
    world.close()
    assert not os.path.exists(path)
    world.close()  # twice is fine
    with pytest.raises(BridgeError, match="closed"):
        world.publish(_frame(0), _truth(1))


def test_handshake_and_header(name):
    with WorldEndpoint(name, small(60, 80), lockstep=False) as world:
        with pytest.raises(BridgeTimeout, match="no driver attached"):
            world.wait_for_driver(timeout=0.05)
        assert not world.driver_attached
        with DriverEndpoint(name, attach_timeout=1) as driver:
            world.wait_for_driver(timeout=1)
            assert world.driver_attached and world.driver_pid == os.getpid()
            cam = driver.layout.cameras[0]
            assert (cam.name, cam.height, cam.width, cam.channels, driver.lockstep) == ("front", 60, 80, 3, False)
            assert driver.declaration == small(60, 80) and driver.world == "highway"
            assert driver.world_pid == os.getpid()
            assert world.latest_action() is None
            seq = world.publish(_frame(7, 60, 80), _truth(1), 0.1)
            msg = driver.wait_frame(timeout=1)
            assert msg.seq == seq == 1 and msg.frame.shape == (60, 80, 3) and (msg.frame == 7).all()
            np.testing.assert_array_equal(msg.record, _truth(1))
            assert msg.t == pytest.approx(0.1) and world.driver_seen_seq == 1
            with pytest.raises(BridgeTimeout, match="no frame"):
                driver.wait_frame(timeout=0.05)
            est = np.linspace(0, 1, ESTIMATE_LEN)
            driver.send_action(msg.seq, Action(0.25, 0.5, 0.0), est)
            act = world.latest_action()
            assert isinstance(act, ActionMsg) and act.seq == 1 and same(act.action, Action(0.25, 0.5, 0.0))
            np.testing.assert_array_equal(act.estimate, est)
            driver.send_action(msg.seq, [0.0, 0.0, 1.0])
            assert not world.wait_action(1, timeout=1).has_estimate


def test_frames_are_copies_and_mapping_is_refused(name):
    with WorldEndpoint(name, small(4, 5)) as world, DriverEndpoint(name) as driver:
        world.publish(_frame(1, 4, 5), {n: 1.0 for n in HIGHWAY.truth_names})   # a mapping is packed by name
        msg = driver.wait_frame(timeout=1)
        world.publish(_frame(2, 4, 5), _truth(2))
        world.publish(_frame(3, 4, 5), _truth(3))   # overwrites the slot of frame 1
        assert (msg.frame == 1).all() and (msg.record == 1).all()
        assert driver.wait_frame(timeout=1).seq == 3   # the newest frame
        with pytest.raises(ValueError, match=r"\(4, 5, 3\)"):
            world.publish(np.zeros((4, 5, 3), np.float32), _truth(4))
        with pytest.raises(ValueError, match="truth record"):
            world.publish(_frame(0, 4, 5), np.zeros(5))
        with pytest.raises(ValueError, match="lacks"):
            world.publish(_frame(0, 4, 5), {"speed": 1.0})
        with pytest.raises(ValueError, match="estimate must hold 19 values"):
            driver.send_action(3, Action(), np.zeros(13))
        with pytest.raises(ValueError, match=r"action must hold 3 values \(steer, accel, brake\)"):
            driver.send_action(3, [0.0, 1.0])


def test_pause_and_driver_mode_are_shared(name):
    with WorldEndpoint(name, small(2, 2)) as world, DriverEndpoint(name) as driver:
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
    world = WorldEndpoint(name, small(2, 2))
    with DriverEndpoint(name) as driver:
        world.publish(_frame(0, 2, 2), _truth(1))
        world.close()
        assert driver.wait_frame(timeout=1).seq == 1   # frames published before the close still arrive
        assert driver.wait_frame(timeout=1) is None
        driver.send_action(1, Action())                # goes nowhere, raises nothing
    assert not os.path.exists(f"/dev/shm/{name}")


def test_driver_detach_is_reported_to_the_world(name):
    with WorldEndpoint(name, small(2, 2)) as world:
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
    world = WorldEndpoint(name, small(2, 2))
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
            "from tests.shm_bridge.records import small\n"
            "with WorldEndpoint(sys.argv[1], small(2, 2)) as w:\n"
            "    w.wait_for_driver(5); w.publish(__import__('numpy').zeros((2, 2, 3), 'u1'), [0.0] * 31)\n"
            "    w.wait_action(1, 5)\n")
    proc = subprocess.Popen([sys.executable, "-c", code, name], cwd=REPO)
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
    with WorldEndpoint(name, small(2, 2)) as world:
        world._u32[layout.OFFSET["version"] // 4] = 1
        with pytest.raises(ProtocolMismatch, match=f"shared memory '{name}' has protocol version 1, "
                                                   "this driver speaks 2"):
            DriverEndpoint(name, attach_timeout=1)
        world._u32[layout.OFFSET["version"] // 4] = 2
        world._u64[layout.OFFSET["layout_size"] // 8] += 64
        with pytest.raises(ProtocolMismatch, match="layout_size"):
            DriverEndpoint(name, attach_timeout=1)
        world._u64[layout.OFFSET["layout_size"] // 8] -= 64
        with DriverEndpoint(name, attach_timeout=1):
            pass


def test_a_version_1_driver_is_refused_in_one_line(name, tmp_path):
    """The previous release's check, verbatim: it reads the version word at offset 8 and names both versions."""
    code = ("import sys, mmap, os, struct\n"
            "fd = os.open('/dev/shm/' + sys.argv[1], os.O_RDWR); m = mmap.mmap(fd, 512)\n"
            "assert m[:8] == b'DSBRIDGE'; v = struct.unpack_from('<I', m, 8)[0]\n"
            "sys.exit(f\"shared memory '{sys.argv[1]}' has protocol version {v}, this driver speaks 1\") if v != 1 "
            "else None\n")
    with WorldEndpoint(name, small(2, 2)):
        r = subprocess.run([sys.executable, "-c", code, name], capture_output=True, text=True, timeout=20)
    assert r.returncode == 1
    assert r.stderr.strip() == f"shared memory '{name}' has protocol version 2, this driver speaks 1"


def test_a_driver_checks_the_header_against_what_it_needs(name):
    with WorldEndpoint(name, small(2, 2)) as world, DriverEndpoint(name, attach_timeout=1) as driver:
        driver.require(world="highway", cameras=["front", ("front", (2, 2))], truth=["speed", "lanes"],
                       action=["steer", "accel", "brake"], estimate=["dist_MM"])
        with pytest.raises(ProtocolMismatch, match="serves world 'highway', not 'sidewalk'"):
            driver.require(world="sidewalk")
        with pytest.raises(ProtocolMismatch, match="no camera 'left'"):
            driver.require(cameras=["left"])
        with pytest.raises(ProtocolMismatch, match="camera 'front' is 2x2, not 280x210"):
            driver.require(cameras=[("front", (210, 280))])
        with pytest.raises(ProtocolMismatch, match="truth record lacks colour"):
            driver.require(truth=["speed", "colour"])
        with pytest.raises(ProtocolMismatch, match=r"action is \(steer, accel, brake\), not \(steer, motor\)"):
            driver.require(action=["steer", "motor"])
        with pytest.raises(ProtocolMismatch, match="no behavioural mode furtive"):
            driver.require(modes=["furtive"])
        assert world.driver_attached


def test_the_end_of_a_run_is_explained_to_the_driver(name):
    world = WorldEndpoint(name, small(2, 2))
    with DriverEndpoint(name, attach_timeout=1) as driver:
        assert driver.end_reason == "none"
        world.publish(_frame(0, 2, 2), _truth(1))
        world.end("host lost")
        assert driver.wait_frame(timeout=1).seq == 1
        assert driver.wait_frame(timeout=1) is None and driver.end_reason == "host lost"
    with pytest.raises(ValueError, match="end reason"):
        WorldEndpoint(name, small(2, 2)).end("bored")


def test_a_driver_ends_the_run_in_order(name):
    with WorldEndpoint(name, small(2, 2)) as world:
        driver = DriverEndpoint(name, attach_timeout=1)
        seq = world.publish(_frame(0, 2, 2), _truth(1))
        driver.finish()
        with pytest.raises(PeerGone) as e:
            world.wait_action(seq, timeout=1)
        assert e.value.finished and e.value.orderly and "finished the run" in str(e.value)
    name2 = name + "-b"
    try:
        with WorldEndpoint(name2, small(2, 2)) as world:
            driver = DriverEndpoint(name2, attach_timeout=1)
            seq = world.publish(_frame(0, 2, 2), _truth(1))
            driver.close()   # leaving without finishing is not a success
            with pytest.raises(PeerGone) as e:
                world.wait_action(seq, timeout=1)
            assert e.value.orderly and not e.value.finished
    finally:
        assert not os.path.exists(f"/dev/shm/{name2}")


def test_behavioural_mode_is_a_shared_flag(name):
    from core import worlds
    with WorldEndpoint(name, worlds.get("sidewalk")) as world, DriverEndpoint(name, attach_timeout=1) as driver:
        assert world.behaviour == driver.behaviour == "direct"
        driver.behaviour = "furtive"
        assert world.behaviour == "furtive"
        frames = tuple(np.zeros(c.shape, np.uint8) for c in driver.declaration.cameras)
        world.publish(frames, np.zeros(len(driver.declaration.truth)))
        assert driver.wait_frame(timeout=1).behaviour == 2
        with pytest.raises(ValueError, match="behavioural mode must be one of direct, follow, furtive"):
            world.behaviour = "sneaky"
    with WorldEndpoint(name, small(2, 2)) as world:
        assert world.behaviour is None


def test_foreign_file_is_refused_and_left_alone(name):
    path = f"/dev/shm/{name}"
    with open(path, "wb") as f:
        f.write(b"NOTOURS!" + bytes(1024))
    try:
        with pytest.raises(ProtocolMismatch, match="not a drivestudio bridge segment"):
            DriverEndpoint(name, attach_timeout=1)
        with pytest.raises(BridgeError, match="already exists and is not a bridge segment"):
            WorldEndpoint(name, HIGHWAY)
        assert os.path.exists(path)
    finally:
        os.unlink(path)


def test_name_of_a_live_world_is_refused(name):
    with WorldEndpoint(name, small(2, 2)):
        with pytest.raises(BridgeError, match=rf"in use by another world process \(pid {os.getpid()}\)"):
            WorldEndpoint(name, small(2, 2))


def test_leftover_of_a_dead_world_is_replaced(name):
    old = WorldEndpoint(name, small(2, 2))
    old._i32[layout.OFFSET["world_pid"] // 4] = _dead_pid()   # as if its process had been killed
    ino = os.stat(f"/dev/shm/{name}").st_ino
    with WorldEndpoint(name, small(2, 2)) as new:
        assert os.stat(f"/dev/shm/{name}").st_ino != ino
        old.close()                                       # must not remove the new world's segment
        assert os.path.exists(f"/dev/shm/{name}")
        with DriverEndpoint(name, attach_timeout=1) as driver:
            assert driver.world_pid == os.getpid()
            new.publish(_frame(0, 2, 2), _truth(1))
            assert driver.wait_frame(timeout=1).seq == 1


def test_driver_removes_a_leftover_and_waits_for_a_new_world(name):
    old = WorldEndpoint(name, small(2, 2))
    old._i32[layout.OFFSET["world_pid"] // 4] = _dead_pid()
    with pytest.raises(BridgeTimeout):
        DriverEndpoint(name, attach_timeout=0.2)
    assert not os.path.exists(f"/dev/shm/{name}")
    old.close()


def test_second_driver_is_refused(name):
    with WorldEndpoint(name, small(2, 2)), DriverEndpoint(name):
        code = "import sys; from shm_bridge.endpoints import DriverEndpoint; DriverEndpoint(sys.argv[1], 1)"
        r = subprocess.run([sys.executable, "-c", code, name], capture_output=True, text=True, timeout=20)
        assert r.returncode != 0
        assert f"shared memory '{name}' already has a driver (pid {os.getpid()})" in r.stderr


@pytest.mark.parametrize("bad", ["", "a/b", "../x", ".hidden", "-x", "x" * 201, "x" * 300, "sp ace"])
def test_bad_names_are_refused(bad):
    from shm_bridge.errors import BadName
    with pytest.raises(BadName, match="bad shared-memory name"):
        WorldEndpoint(bad, HIGHWAY)


def test_forked_child_does_not_end_the_parents_run(name):
    with WorldEndpoint(name, small(2, 2)) as world:
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


def version_1_segment(name: str, world_pid: int) -> None:
    """/dev/shm/NAME as a world of protocol version 1 left it: the highway's 210 x 280 frame, its header fields at
    their version-1 offsets (byte_order at 60, world_state at 68, world_pid at 72; offset 24 holds the height)."""
    import struct
    slot_size = -(-(256 + 210 * 280 * 3) // 64) * 64
    header = bytearray(512)
    header[0:8] = b"DSBRIDGE"
    struct.pack_into("<IIQ", header, 8, 1, 512, 512 + 2 * slot_size)
    struct.pack_into("<IIIIIIIIII", header, 24, 210, 280, 3, 210 * 280 * 3, 28, 14, 2, slot_size, 0, 0x01020304)
    struct.pack_into("<Ii", header, 68, 1, world_pid)
    fd = os.open(f"/dev/shm/{name}", os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        os.ftruncate(fd, 512 + 2 * slot_size)
        os.pwrite(fd, bytes(header), 0)
    finally:
        os.close(fd)


def test_a_real_version_1_segment_is_refused_naming_both_versions(name):
    """The version word is read before byte_order, whose offset changed (24 now, 60 in version 1)."""
    version_1_segment(name, os.getpid())
    try:
        with pytest.raises(ProtocolMismatch, match=f"^shared memory '{name}' has protocol version 1, this driver "
                                                   "speaks 2$"):
            DriverEndpoint(name, attach_timeout=1)
        assert os.path.exists(f"/dev/shm/{name}")   # a live world's segment is not touched
    finally:
        os.unlink(f"/dev/shm/{name}")


def test_the_other_byte_order_is_named_as_such(name):
    with WorldEndpoint(name, small(2, 2)) as world:
        world._u32[layout.OFFSET["version"] // 4] = 2 << 24   # version 2 as a big-endian writer stores it
        with pytest.raises(ProtocolMismatch, match="written with the other byte order"):
            DriverEndpoint(name, attach_timeout=1)
        world._u32[layout.OFFSET["version"] // 4] = 2


def test_a_run_serves_one_driver(name):
    """After its driver has left, a world is ending the run: a second driver is refused, not attached."""
    from shm_bridge.errors import Refused
    with WorldEndpoint(name, small(2, 2)) as world:
        with DriverEndpoint(name, attach_timeout=1):
            world.wait_for_driver(timeout=1)
        with pytest.raises(Refused, match="has already served a driver"):
            DriverEndpoint(name, attach_timeout=1)
