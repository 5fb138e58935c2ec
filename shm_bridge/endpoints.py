"""The two ends of the bridge: WorldEndpoint (creates the segment, publishes frames) and DriverEndpoint (attaches,
takes frames, sends actions). docs/shm-protocol.md describes what they do byte by byte.

    with WorldEndpoint("run1") as world:            # the world process
        world.wait_for_driver(timeout=30)
        while ...:
            seq = world.publish(obs.frame, truth)
            act = world.wait_action(seq).action       # lock-step; free-running: world.latest_action()

    with DriverEndpoint("run1") as driver:          # the driver process
        while (msg := driver.wait_frame()) is not None:
            driver.send_action(msg.seq, Action(...), estimate)

Waiting spins briefly, then sleeps on a futex word in the segment in slices of SLICE seconds; between slices it
checks that the peer lives (pid exists and is not a zombie, heartbeat younger than peer_timeout). A dead peer
makes the survivor remove the segment and raise PeerGone. Both endpoints close on exit of the `with` block, on
close(), on garbage collection and at interpreter exit.
"""
from __future__ import annotations

import fcntl
import os
import threading
import time
import weakref
from dataclasses import dataclass, field

import numpy as np

from shm_bridge import futex, layout
from shm_bridge.errors import BridgeError, BridgeTimeout, PeerGone, ProtocolMismatch
from shm_bridge.layout import (CONTROL_SIZE, DRIVER_ATTACHED, DRIVER_DETACHED, DRIVER_MODES, DRIVER_NONE,
                               MAGIC, N_ACTION, N_INDICATORS, OFFSET, SLOT_COUNT, SLOT_HEADER_SIZE, SLOT_OFFSET,
                               TRUTH_LEN, VERSION, WORLD_CLOSED, WORLD_RUNNING)
from shm_bridge.segment import Segment, pid_alive, shm_path, unlink_if_same, validate_name
from shm_bridge.signals import Terminated, exit_on_sigterm
from shm_bridge.vocabulary import INDICATORS, Action

__all__ = ["WorldEndpoint", "DriverEndpoint", "FrameMsg", "ActionMsg", "BridgeError", "PeerGone",
           "ProtocolMismatch", "BridgeTimeout", "Terminated", "exit_on_sigterm"]

SLICE = 0.1                 # [s] longest single futex sleep; liveness is checked between slices
HEARTBEAT_INTERVAL = 0.2    # [s] how often each side refreshes its heartbeat
DEFAULT_SPIN = 100e-6       # [s] busy-wait before sleeping on the futex
_MASK32 = 0xFFFFFFFF
_NOTHING = object()

# word indices into the whole-mapping uint32 / int32 / uint64 views
_U32 = {n: OFFSET[n] // 4 for n in ("version", "header_size", "height", "width", "channels", "frame_size",
                                    "truth_len", "n_indicators", "slot_count", "slot_size", "mode", "byte_order",
                                    "driver_bell", "world_state", "world_bell", "driver_state", "paused",
                                    "driver_mode", "world_pid", "driver_pid")}
_U64 = {n: OFFSET[n] // 8 for n in ("layout_size", "world_heartbeat_ns", "frame_seq", "driver_heartbeat_ns",
                                    "driver_seen_seq", "action_lock", "action_seq")}
_ACTION_BLOCK = (OFFSET["action"], OFFSET["estimate"] + 8 * N_INDICATORS)   # action then estimate, contiguous
assert OFFSET["estimate"] == OFFSET["action"] + 8 * N_ACTION


# --- messages ------------------------------------------------------------------------------------------------------
@dataclass
class FrameMsg:
    """One frame as the driver took it: seq (1, 2, ...), frame (h, w, 3) uint8 RGB and truth (TRUTH_LEN
    float64, layout.TRUTH_FIELDS), both copies; paused and driver_mode as they were when it was taken."""

    seq: int
    frame: np.ndarray
    truth: np.ndarray
    paused: bool = False
    driver_mode: str = "network"

    @property
    def indicators(self) -> np.ndarray:
        """The 14 true indicators, canonical order."""
        return self.truth[:N_INDICATORS]

    @property
    def t(self) -> float:
        """Simulated time [s]."""
        return float(self.truth[layout.TRUTH_INDEX["t"]])

    @property
    def speed(self) -> float:
        """Host car's speed [m/s]."""
        return float(self.truth[layout.TRUTH_INDEX["speed"]])

    @property
    def ego(self) -> np.ndarray:
        """[x, y, yaw, s, d] of the host car."""
        return layout.truth_ego(self.truth)

    def truth_dict(self) -> dict:
        return layout.unpack_truth(self.truth)


@dataclass
class ActionMsg:
    """The driver's answer to frame `seq`: the action and its estimate of the 14 indicators (NaN: none sent)."""

    seq: int
    action: Action
    estimate: np.ndarray = field(default_factory=lambda: np.full(N_INDICATORS, np.nan))

    @property
    def has_estimate(self) -> bool:
        return bool(np.isfinite(self.estimate).any())

    def estimate_dict(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(INDICATORS, self.estimate)}


# --- resources shared by the endpoint, its heartbeat thread and its finalizer (never the endpoint itself) --------
def _heartbeat(u64: memoryview, index: int, stop: threading.Event) -> None:
    while not stop.wait(HEARTBEAT_INTERVAL):
        try:
            u64[index] = time.monotonic_ns()
        except (ValueError, TypeError):   # the view was released under us: the endpoint is closing
            return


class _Link:
    """The mapping and what to do with it at the end: mark our side closed, wake the peer, maybe unlink."""

    def __init__(self, segment: Segment, state_word: str, closed_state: int, peer_bell: str, heartbeat: str,
                 unlink: bool):
        self.segment = segment
        self.state_index = _U32[state_word]
        self.closed_state = closed_state
        self.peer_bell = peer_bell
        self.unlink = unlink
        self.owner = os.getpid()   # a forked child inherits the object but must not end the owner's run
        self.stop = threading.Event()
        self.thread = threading.Thread(target=_heartbeat, args=(segment.u64, _U64[heartbeat], self.stop),
                                       name=f"shm-heartbeat-{segment.name}", daemon=True)

    def ring(self) -> None:
        seg = self.segment
        i = _U32[self.peer_bell]
        seg.u32[i] = (seg.u32[i] + 1) & _MASK32
        futex.wake(seg.address + OFFSET[self.peer_bell])

    def shutdown(self) -> None:
        seg = self.segment
        if os.getpid() != self.owner:
            seg.close()
            return
        try:
            seg.u32[self.state_index] = self.closed_state
            self.ring()
        except (ValueError, OSError):
            pass
        if self.unlink:
            seg.unlink()
        self.stop.set()
        if self.thread.is_alive() and self.thread is not threading.current_thread():
            self.thread.join(timeout=1.0)
        seg.close()


# --- the common part of both endpoints -----------------------------------------------------------------------------
class _Endpoint:
    _role = "?"
    _peer_role = "?"

    def _setup(self, segment: Segment, link: _Link, own_bell: str, peer_timeout: float | None, spin: float):
        self._seg = segment
        self._link = link
        self._u32, self._i32, self._u64 = segment.u32, segment.i32, segment.u64
        self._own_bell = _U32[own_bell]
        self._own_bell_address = segment.address + OFFSET[own_bell]
        self._peer_timeout_ns = None if peer_timeout is None else int(peer_timeout * 1e9)
        self._spin_ns = int(max(0.0, spin) * 1e9)
        self._next_check = 0
        self._gone: PeerGone | None = None
        self._closed = False
        h, w = self._u32[_U32["height"]], self._u32[_U32["width"]]
        frame_size, size = self._u32[_U32["frame_size"]], self._u32[_U32["slot_size"]]
        self.height, self.width, self.channels = int(h), int(w), int(self._u32[_U32["channels"]])
        self.lockstep = self._u32[_U32["mode"]] == layout.MODE_LOCKSTEP
        buf = segment.buf
        self._slot_lock, self._slot_seq, self._slot_truth, self._slot_frame = [], [], [], []
        for i in range(SLOT_COUNT):
            base = CONTROL_SIZE + i * size
            self._slot_lock.append((base + SLOT_OFFSET["lock"]) // 8)
            self._slot_seq.append((base + SLOT_OFFSET["seq"]) // 8)
            t0 = base + SLOT_OFFSET["truth"]
            self._slot_truth.append(buf[t0:t0 + 8 * TRUTH_LEN].view(np.float64))
            f0 = base + SLOT_HEADER_SIZE
            self._slot_frame.append(buf[f0:f0 + frame_size].reshape(self.height, self.width, self.channels))
        self._action_block = buf[_ACTION_BLOCK[0]:_ACTION_BLOCK[1]].view(np.float64)
        self._finalizer = weakref.finalize(self, link.shutdown)
        link.thread.start()

    # --- shared flags ----------------------------------------------------------------------------------------------
    @property
    def name(self) -> str:
        return self._seg.name

    @property
    def paused(self) -> bool:
        """The pause flag; either side may set it (the other side's waits are woken)."""
        self._require_open()
        return bool(self._u32[_U32["paused"]])

    @paused.setter
    def paused(self, value: bool) -> None:
        self._require_open()
        self._u32[_U32["paused"]] = 1 if value else 0
        self._link.ring()

    @property
    def driver_mode(self) -> str:
        """Who drives: "network" (the driver's actions) or "manual" (a human or the expert)."""
        self._require_open()
        v = self._u32[_U32["driver_mode"]]
        return DRIVER_MODES[v] if v < len(DRIVER_MODES) else f"unknown({v})"

    @driver_mode.setter
    def driver_mode(self, value: str | int) -> None:
        self._require_open()
        if isinstance(value, str):
            if value not in DRIVER_MODES:
                raise ValueError(f"driver_mode must be one of {', '.join(DRIVER_MODES)}, got {value!r}")
            value = DRIVER_MODES.index(value)
        elif value not in range(len(DRIVER_MODES)):
            raise ValueError(f"driver_mode must be 0 (network) or 1 (manual), got {value!r}")
        self._u32[_U32["driver_mode"]] = int(value)
        self._link.ring()

    # --- waiting and liveness --------------------------------------------------------------------------------------
    def _require_open(self) -> None:
        if self._closed:
            raise BridgeError(f"the {self._role} endpoint of {self.name!r} is closed")

    def _wait(self, ready, timeout: float | None, what: str):
        """Until ready() returns something other than _NOTHING: spin, then futex-sleep in slices."""
        r = ready()
        if r is not _NOTHING:
            return r
        if self._gone is not None:
            raise self._gone_again()
        clock = time.perf_counter_ns
        end = clock() + self._spin_ns
        while clock() < end:
            r = ready()
            if r is not _NOTHING:
                return r
        deadline = None if timeout is None else time.monotonic() + timeout
        u32, bell, address = self._u32, self._own_bell, self._own_bell_address
        while True:
            value = u32[bell]
            r = ready()
            if r is not _NOTHING:
                return r
            self._check_peer()
            nap = SLICE
            if deadline is not None:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise BridgeTimeout(f"{what} within {timeout:g} s")
                nap = min(nap, left)
            futex.wait(address, value, nap)

    def _check_peer(self) -> None:
        """Raise PeerGone when the peer left or died; the pid and heartbeat tests run at most every SLICE."""
        if self._gone is not None:
            raise self._gone_again()
        state, pid = self._peer_state()
        if state is None:
            return
        if state == "left":
            raise self._lose(f"the {self._peer_role} (pid {pid}) closed the connection", pid, orderly=True)
        now = time.monotonic_ns()
        if now < self._next_check:
            return
        self._next_check = now + int(SLICE * 1e9)
        if not pid_alive(pid):
            raise self._lose(f"the {self._peer_role} process (pid {pid}) died", pid)
        if self._peer_timeout_ns is not None:
            age = now - self._u64[self._peer_heartbeat]
            if age > self._peer_timeout_ns:
                raise self._lose(f"the {self._peer_role} process (pid {pid}) stopped responding "
                                 f"(no heartbeat for {age / 1e9:.1f} s)", pid)

    def _lose(self, message: str, pid: int, orderly: bool = False) -> PeerGone:
        """Remember that the peer is gone, remove the segment (the run is over) and return the exception."""
        self._gone = PeerGone(message, pid=pid, orderly=orderly)
        self._link.unlink = True
        self._seg.unlink()
        return self._gone

    def _gone_again(self) -> PeerGone:
        """A fresh PeerGone like the first one (re-raising one instance would pile up tracebacks)."""
        g = self._gone
        return PeerGone(str(g), pid=g.pid, orderly=g.orderly)

    def _peer_state(self):
        raise NotImplementedError

    def _before_close(self) -> None:
        pass

    # --- lifecycle -------------------------------------------------------------------------------------------------
    def close(self) -> None:
        """Mark this side closed, wake the peer, stop the heartbeat, unmap (and, for the world, unlink)."""
        if self._closed:
            return
        self._closed = True
        self._before_close()
        self._slot_truth = self._slot_frame = self._action_block = None
        self._u32 = self._i32 = self._u64 = None
        self._finalizer()

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


# --- the world side ------------------------------------------------------------------------------------------------
class WorldEndpoint(_Endpoint):
    """Creates /dev/shm/NAME (0600), publishes frames with their truth and reads the driver's actions.

    lockstep=True: after publish(frame n) the world calls wait_action(n) (TORCS's `written` flag).
    lockstep=False (free-running): the world never waits; latest_action() gives the newest action, if any.
    peer_timeout: seconds without a driver heartbeat before the driver counts as dead (None: pid test only).
    spin: seconds of busy-waiting before a wait sleeps on the futex.
    """

    _role = "world"
    _peer_role = "driver"

    def __init__(self, name: str, height: int = 210, width: int = 280, lockstep: bool = True,
                 peer_timeout: float | None = 2.0, *, spin: float = DEFAULT_SPIN):
        layout.check_native_byte_order()
        if not futex.available():
            raise BridgeError("the shared-memory bridge needs Linux futexes (unsupported platform)")
        for label, v in (("height", height), ("width", width)):
            if not isinstance(v, (int, np.integer)) or v <= 0:
                raise ValueError(f"{label} must be a positive integer, got {v!r}")
        height, width = int(height), int(width)
        if height * width * layout.CHANNELS > 0x7FFFFFFF - SLOT_HEADER_SIZE:
            raise ValueError(f"a {height}x{width} frame is too large for the bridge")
        seg = _create(name, layout.layout_size(height, width))
        try:
            header = seg.buf[:CONTROL_SIZE].view(layout.CONTROL_DTYPE)[0]
            for key, value in layout.header_values(height, width, lockstep).items():
                header[key] = value
            del header
            seg.i32[_U32["world_pid"]] = os.getpid()
            seg.u64[_U64["world_heartbeat_ns"]] = time.monotonic_ns()
            seg.u32[_U32["world_state"]] = WORLD_RUNNING
            seg.buf[:len(MAGIC)] = np.frombuffer(MAGIC, dtype=np.uint8)   # last: the segment is ready
            link = _Link(seg, "world_state", WORLD_CLOSED, "driver_bell", "world_heartbeat_ns", unlink=True)
        except BaseException:
            seg.unlink()
            seg.close()
            raise
        self._peer_heartbeat = _U64["driver_heartbeat_ns"]
        self._seq = 0
        self._setup(seg, link, "world_bell", peer_timeout, spin)

    # --- the driver ------------------------------------------------------------------------------------------------
    def _peer_state(self):
        state = self._u32[_U32["driver_state"]]
        if state == DRIVER_NONE:
            return None, 0
        pid = self._i32[_U32["driver_pid"]]
        return ("left" if state == DRIVER_DETACHED else "attached"), pid

    @property
    def driver_attached(self) -> bool:
        self._require_open()
        return self._u32[_U32["driver_state"]] == DRIVER_ATTACHED

    @property
    def driver_pid(self) -> int:
        """The driver's pid (0 before one attached)."""
        self._require_open()
        return int(self._i32[_U32["driver_pid"]])

    @property
    def driver_seen_seq(self) -> int:
        """The seq of the newest frame the driver has taken (free-running: how far behind it is)."""
        self._require_open()
        return int(self._u64[_U64["driver_seen_seq"]])

    @property
    def seq(self) -> int:
        """The seq of the newest published frame (0: none yet)."""
        return self._seq

    def wait_for_driver(self, timeout: float | None = None) -> None:
        """Handshake: return once a driver has attached; BridgeTimeout after `timeout` seconds."""
        self._require_open()
        state = _U32["driver_state"]

        def ready():
            return True if self._u32[state] != DRIVER_NONE else _NOTHING

        self._wait(ready, timeout, f"no driver attached to shared memory {self.name!r}")

    # --- frames ----------------------------------------------------------------------------------------------------
    def publish(self, frame: np.ndarray, truth) -> int:
        """Write frame (h, w, 3) uint8 and its truth record (TRUTH_LEN float64 or a mapping) as the next frame;
        return its seq. Never waits. Raises PeerGone when the driver has died or left."""
        self._require_open()
        if not isinstance(frame, np.ndarray) or frame.dtype != np.uint8 or \
                frame.shape != (self.height, self.width, self.channels):
            shape = getattr(frame, "shape", None)
            dtype = getattr(frame, "dtype", type(frame).__name__)
            raise ValueError(f"frame must be a ({self.height}, {self.width}, {self.channels}) uint8 array, "
                             f"got {shape} {dtype}")
        truth = layout.check_truth(truth)
        self._check_peer()
        seq = self._seq + 1
        i = seq % SLOT_COUNT
        u64, lock = self._u64, self._slot_lock[i]
        version = u64[lock]
        u64[lock] = version + 1                 # odd: being written
        u64[self._slot_seq[i]] = seq
        self._slot_truth[i][:] = truth
        np.copyto(self._slot_frame[i], frame)
        u64[lock] = version + 2                 # even: complete
        u64[_U64["frame_seq"]] = seq
        self._seq = seq
        self._link.ring()
        return seq

    # --- actions ---------------------------------------------------------------------------------------------------
    def _read_action(self):
        """(seq, 17 float64 copy) of the action record, or None while the driver is in the middle of a write."""
        u64, lock, aseq = self._u64, _U64["action_lock"], _U64["action_seq"]
        for _ in range(1000):
            version = u64[lock]
            if version & 1:
                continue
            seq = u64[aseq]
            values = self._action_block.copy()
            if u64[lock] == version:
                return seq, values
        return None

    @staticmethod
    def _message(seq: int, values: np.ndarray) -> ActionMsg:
        return ActionMsg(int(seq), Action(float(values[0]), float(values[1]), float(values[2])),
                         values[N_ACTION:])

    def wait_action(self, seq: int, timeout: float | None = None) -> ActionMsg:
        """Lock-step: wait for the driver's action for frame `seq` (or a later one) and return it.

        BridgeTimeout after `timeout` seconds, PeerGone when the driver died or left."""
        self._require_open()

        def ready():
            r = self._read_action()
            if r is not None and r[0] >= seq:
                return self._message(*r)
            return _NOTHING

        return self._wait(ready, timeout, f"no action for frame {seq} from the driver")

    def latest_action(self) -> ActionMsg | None:
        """Free-running: the newest action the driver sent (None before the first). Never waits."""
        self._require_open()
        self._check_peer()
        r = self._read_action()
        if r is None or r[0] == 0:
            return None
        return self._message(*r)


def _create(name: str, size: int) -> Segment:
    """Create the segment; a leftover of a dead world under the same name is removed first."""
    validate_name(name)
    for attempt in range(3):
        try:
            return Segment.create(name, size)
        except FileExistsError:
            problem = _stale_or_busy(name)
            if problem is not None:
                raise BridgeError(problem) from None
    raise BridgeError(f"cannot create shared memory {name!r}: the name keeps being taken")


def _stale_or_busy(name: str) -> str | None:
    """Remove /dev/shm/NAME when it is a bridge segment whose world is dead (None); else why it must stay."""
    seg = Segment.open(name, CONTROL_SIZE)
    if seg is None:
        return None if not os.path.exists(shm_path(name)) else \
            f"shared memory {name!r} already exists (being created, or not a bridge segment)"
    try:
        if bytes(seg.buf[:len(MAGIC)]) != MAGIC or seg.u32[_U32["version"]] != VERSION:
            return (f"shared memory {name!r} already exists and is not a version-{VERSION} bridge segment "
                    f"(remove {shm_path(name)} if it is stale)")
        pid = seg.i32[_U32["world_pid"]]
        if seg.u32[_U32["world_state"]] != WORLD_CLOSED and pid_alive(pid):
            return f"shared memory {name!r} is in use by another world process (pid {pid})"
        seg.unlink()
        return None
    finally:
        seg.close()


# --- the driver side -----------------------------------------------------------------------------------------------
class DriverEndpoint(_Endpoint):
    """Attaches to the world's segment, takes frames and sends actions.

    attach_timeout: seconds to wait for the world to create the segment. peer_timeout: seconds without a world
    heartbeat before the world counts as dead (None: pid test only). Only one driver may attach at a time.
    """

    _role = "driver"
    _peer_role = "world"

    def __init__(self, name: str, attach_timeout: float = 10.0, peer_timeout: float | None = 2.0, *,
                 spin: float = DEFAULT_SPIN):
        layout.check_native_byte_order()
        if not futex.available():
            raise BridgeError("the shared-memory bridge needs Linux futexes (unsupported platform)")
        name = validate_name(name)
        seg = _attach(name, attach_timeout)
        try:
            try:
                fcntl.flock(seg.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                pid = seg.i32[_U32["driver_pid"]]
                raise BridgeError(f"shared memory {name!r} already has a driver (pid {pid})") from None
            seg.i32[_U32["driver_pid"]] = os.getpid()
            seg.u64[_U64["driver_heartbeat_ns"]] = time.monotonic_ns()
            seg.u32[_U32["driver_state"]] = DRIVER_ATTACHED
            link = _Link(seg, "driver_state", DRIVER_DETACHED, "world_bell", "driver_heartbeat_ns", unlink=False)
            link.ring()
        except BaseException:
            seg.close()
            raise
        self._peer_heartbeat = _U64["world_heartbeat_ns"]
        self._last_seq = 0
        self.discarded_copies = 0   # copies thrown away because the world rewrote the slot meanwhile
        self._setup(seg, link, "driver_bell", peer_timeout, spin)

    def _peer_state(self):
        if self._u32[_U32["world_state"]] == WORLD_CLOSED:
            return None, 0   # the world ended the run in order: wait_frame returns None, actions go nowhere
        return "attached", int(self._i32[_U32["world_pid"]])

    def _before_close(self) -> None:
        if self._u32[_U32["world_state"]] != WORLD_CLOSED and not pid_alive(self._i32[_U32["world_pid"]]):
            self._link.unlink = True   # the world died unnoticed: its segment would be left behind

    @property
    def world_pid(self) -> int:
        self._require_open()
        return int(self._i32[_U32["world_pid"]])

    @property
    def last_seq(self) -> int:
        """The seq of the newest frame this driver has taken (0: none yet)."""
        return self._last_seq

    # --- frames ----------------------------------------------------------------------------------------------------
    def _take_frame(self):
        """The newest frame not yet taken, None when the world closed, else _NOTHING."""
        u64 = self._u64
        seq = u64[_U64["frame_seq"]]
        if seq <= self._last_seq:
            if self._u32[_U32["world_state"]] == WORLD_CLOSED:
                return None
            return _NOTHING
        for _ in range(1000):
            i = seq % SLOT_COUNT
            lock = self._slot_lock[i]
            version = u64[lock]
            if not version & 1 and u64[self._slot_seq[i]] == seq:
                frame = self._slot_frame[i].copy()
                truth = self._slot_truth[i].copy()
                if u64[lock] == version:
                    self._last_seq = seq
                    u64[_U64["driver_seen_seq"]] = seq
                    u32 = self._u32
                    mode = u32[_U32["driver_mode"]]
                    return FrameMsg(int(seq), frame, truth, bool(u32[_U32["paused"]]),
                                    DRIVER_MODES[mode] if mode < len(DRIVER_MODES) else f"unknown({mode})")
                self.discarded_copies += 1
            seq = u64[_U64["frame_seq"]]   # the world moved on while we copied: take the newer frame
        return _NOTHING

    def wait_frame(self, timeout: float | None = None) -> FrameMsg | None:
        """The next frame (lock-step) or the newest one (free-running); None once the world closed the run.

        BridgeTimeout after `timeout` seconds, PeerGone when the world process died."""
        self._require_open()
        return self._wait(self._take_frame, timeout, "no frame from the world")

    # --- actions ---------------------------------------------------------------------------------------------------
    def send_action(self, seq: int, action: Action, estimate: np.ndarray | None = None) -> None:
        """Answer frame `seq` with `action` (an Action or [steer, accel, brake]) and the estimated indicators."""
        self._require_open()
        self._check_peer()
        a = action.as_array() if isinstance(action, Action) else np.asarray(action, dtype=np.float64)
        if a.shape != (N_ACTION,):
            raise ValueError(f"action must be an Action or 3 numbers [steer, accel, brake], got shape {a.shape}")
        if estimate is None:
            est = np.full(N_INDICATORS, np.nan)
        else:
            est = np.asarray(estimate, dtype=np.float64)
            if est.shape != (N_INDICATORS,):
                raise ValueError(f"estimate must hold the {N_INDICATORS} indicators in canonical order, "
                                 f"got shape {est.shape}")
        u64, lock = self._u64, _U64["action_lock"]
        version = u64[lock]
        u64[lock] = version + 1
        u64[_U64["action_seq"]] = int(seq)
        block = self._action_block
        block[:N_ACTION] = a
        block[N_ACTION:] = est
        u64[lock] = version + 2
        self._link.ring()


def _attach(name: str, timeout: float) -> Segment:
    """Open the world's segment, waiting up to `timeout` s for it to appear, and check its header."""
    deadline = time.monotonic() + timeout
    delay = 0.001
    while True:
        seg = Segment.open(name, CONTROL_SIZE)
        if seg is not None:
            try:
                magic = bytes(seg.buf[:len(MAGIC)])
                if magic == MAGIC:
                    problem = _check_header(seg)
                    if problem is None:
                        return seg
                    if problem != "stale":
                        raise ProtocolMismatch(problem)
                elif magic != bytes(len(MAGIC)):
                    raise ProtocolMismatch(f"shared memory {name!r} is not a drivestudio bridge segment "
                                           f"(magic {magic!r}, expected {MAGIC!r})")
            except BaseException:
                seg.close()
                raise
            seg.close()
        if time.monotonic() >= deadline:
            raise BridgeTimeout(f"no world serves shared memory {name!r} "
                                f"(waited {timeout:g} s for {shm_path(name)})")
        time.sleep(delay)   # attaching only: frames and actions never sleep-poll
        delay = min(delay * 2, 0.05)


def _check_header(seg: Segment) -> str | None:
    """None when the header matches this implementation, "stale" for a dead world's leftover (removed),
    else the mismatch in one line."""
    u32, name = seg.u32, seg.name
    if u32[_U32["byte_order"]] != layout.BYTE_ORDER_MARK:
        return f"shared memory {name!r} was written with the other byte order"
    version = u32[_U32["version"]]
    if version != VERSION:
        return f"shared memory {name!r} has protocol version {version}, this driver speaks {VERSION}"
    h, w, c = (int(u32[_U32[k]]) for k in ("height", "width", "channels"))
    declared = int(seg.u64[_U64["layout_size"]])
    expected = layout.layout_size(h, w, c)
    fixed = {"header_size": CONTROL_SIZE, "truth_len": TRUTH_LEN, "n_indicators": N_INDICATORS,
             "slot_count": SLOT_COUNT, "frame_size": h * w * c, "slot_size": layout.slot_size(h * w * c)}
    bad = [f"{k} {u32[_U32[k]]} (expected {v})" for k, v in fixed.items() if u32[_U32[k]] != v]
    if declared != expected or seg.size < declared or bad or c != layout.CHANNELS:
        return (f"shared memory {name!r} declares a layout of {declared} bytes ({seg.size} mapped) for "
                f"{h}x{w}x{c} frames, this driver expects {expected}" + (f": {', '.join(bad)}" if bad else ""))
    pid = seg.i32[_U32["world_pid"]]
    if u32[_U32["world_state"]] == WORLD_CLOSED or not pid_alive(pid):
        unlink_if_same(seg.path, seg.dev, seg.ino)   # a dead world's leftover: remove it, wait for a new one
        return "stale"
    return None
