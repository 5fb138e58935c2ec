"""The two ends of the bridge: WorldEndpoint (creates the segment, publishes frames) and DriverEndpoint (attaches,
takes frames, sends actions). docs/shm-protocol.md describes what they do byte by byte.

    with WorldEndpoint("run1", declaration) as world:     # the world process
        world.wait_for_driver(timeout=30)
        while ...:
            seq = world.publish(obs.frames, obs.record, obs.t)
            act = world.wait_action(seq).action              # lock-step; free-running: world.latest_action()
        world.end("finished")                                 # or "host lost", "interrupted", ...

    with DriverEndpoint("run1") as driver:                  # the driver process
        decl = driver.declaration                             # what the world declared in the header
        while (msg := driver.wait_frame()) is not None:
            driver.send_action(msg.seq, action, estimate)
        print(driver.end_reason)

Everything that depends on the world (cameras, record lengths, names) comes from its WorldDeclaration on the world
side and from the header on the driver side; a driver checks the header against what it needs with `require`.

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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from core.declaration import DeclarationError, WorldDeclaration
from core.processes import pid_alive
from core.signals import Terminated, exit_on_sigterm
from shm_bridge import futex, layout
from shm_bridge.errors import BridgeError, BridgeTimeout, PeerGone, ProtocolMismatch, Refused
from shm_bridge.layout import (
    ACTION_OFFSET,
    ACTION_VALUES,
    DRIVER_ATTACHED,
    DRIVER_DETACHED,
    DRIVER_MODES,
    DRIVER_NONE,
    DRIVER_STATUSES,
    END_REASONS,
    FIXED_SIZE,
    MAGIC,
    OFFSET,
    SLOT_COUNT,
    SLOT_OFFSET,
    SLOT_TRUTH,
    STATUS_FAILED,
    STATUS_FINISHED,
    VERSION,
    WORLD_CLOSED,
    WORLD_RUNNING,
    Layout,
)
from shm_bridge.segment import SHM_DIR, Segment, shm_path, unlink_if_same, validate_name

__all__ = ["WorldEndpoint", "DriverEndpoint", "FrameMsg", "ActionMsg", "BridgeError", "PeerGone",
           "ProtocolMismatch", "BridgeTimeout", "Terminated", "exit_on_sigterm"]

SLICE = 0.1                 # [s] longest single futex sleep; liveness is checked between slices
HEARTBEAT_INTERVAL = 0.2    # [s] how often each side refreshes its heartbeat
DEFAULT_SPIN = 100e-6       # [s] busy-wait before sleeping on the futex
DEFAULT_ATTACH_TIMEOUT = 10.0   # [s] a driver waits this long for the world's segment to appear
_MASK32 = 0xFFFFFFFF
_NOTHING = object()

# word indices into the whole-mapping uint32 / int32 / uint64 views
_U32 = {n: OFFSET[n] // 4 for n in ("version", "byte_order", "mode", "driver_bell", "world_state", "world_pid",
                                    "end_reason", "world_bell", "driver_state", "driver_pid", "driver_status",
                                    "paused", "driver_mode", "behaviour")}
_U64 = {n: OFFSET[n] // 8 for n in ("layout_size", "world_heartbeat_ns", "frame_seq", "driver_heartbeat_ns",
                                    "driver_seen_seq")}


# --- messages ------------------------------------------------------------------------------------------------------
@dataclass
class FrameMsg:
    """One frame as the driver took it: seq (1, 2, ...), the images (one (h, w, c) uint8 array per camera, in the
    header's camera order), the truth record (float64, the header's truth names) and the simulated time t, all
    copies; the shared flags as they were when it was taken."""

    seq: int
    frames: tuple
    record: np.ndarray
    t: float
    paused: bool = False
    driver_mode: str = "network"
    behaviour: int = 0

    @property
    def frame(self) -> np.ndarray:
        """The first camera's image."""
        return self.frames[0]


@dataclass
class ActionMsg:
    """The driver's answer to frame `seq`: the action and its estimate (NaN: none sent), float64 arrays."""

    seq: int
    action: np.ndarray
    estimate: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def has_estimate(self) -> bool:
        return bool(np.isfinite(self.estimate).any())


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
    _peer_heartbeat: int   # index in the u64 view of the peer's heartbeat (set by each endpoint's __init__)

    def _setup(self, segment: Segment, layout_: Layout, link: _Link, own_bell: str, peer_timeout: float | None,
               spin: float):
        self._seg = segment
        self._link = link
        self.layout = layout_
        self._u32, self._i32, self._u64 = segment.u32, segment.i32, segment.u64
        self._own_bell = _U32[own_bell]
        self._own_bell_address = segment.address + OFFSET[own_bell]
        self._peer_timeout_ns = None if peer_timeout is None else int(peer_timeout * 1e9)
        self._spin_ns = int(max(0.0, spin) * 1e9)
        self._next_check = 0
        self._gone: PeerGone | None = None
        self._closed = False
        self.lockstep = layout_.lockstep
        self.modes = layout_.modes
        buf = segment.buf
        truth_len = len(layout_.truth)
        self._slot_lock, self._slot_seq, self._slot_t, self._slot_truth, self._slot_images = [], [], [], [], []
        for i in range(SLOT_COUNT):
            base = layout_.slot_offset(i)
            self._slot_lock.append((base + SLOT_OFFSET["lock"]) // 8)
            self._slot_seq.append((base + SLOT_OFFSET["seq"]) // 8)
            t0 = base + SLOT_OFFSET["t"]
            self._slot_t.append(buf[t0:t0 + 8].view(np.float64))
            r0 = base + SLOT_TRUTH
            self._slot_truth.append(buf[r0:r0 + 8 * truth_len].view(np.float64))
            self._slot_images.append(tuple(
                buf[base + c.offset:base + c.offset + c.size].reshape(c.height, c.width, c.channels)
                for c in layout_.cameras))
        a0 = layout_.action_offset
        self._action_lock = (a0 + ACTION_OFFSET["action_lock"]) // 8
        self._action_seq = (a0 + ACTION_OFFSET["action_seq"]) // 8
        self._n_action = len(layout_.action)
        n_values = self._n_action + len(layout_.estimate)
        self._action_block = buf[a0 + ACTION_VALUES:a0 + ACTION_VALUES + 8 * n_values].view(np.float64)
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

    @property
    def behaviour(self) -> str | None:
        """The behavioural mode (a shared flag either side may set); None for a world without modes."""
        self._require_open()
        if not self.modes:
            return None
        v = self._u32[_U32["behaviour"]]
        return self.modes[v] if v < len(self.modes) else f"unknown({v})"

    @behaviour.setter
    def behaviour(self, mode: str) -> None:
        self._require_open()
        if mode not in self.modes:
            raise ValueError(f"behavioural mode must be one of {', '.join(self.modes) or '(none)'}, got {mode!r}")
        self._u32[_U32["behaviour"]] = self.modes.index(mode)
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
        assert g is not None   # called only once the peer is known to be gone
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
        # released views: a later use fails loudly instead of touching an unmapped segment
        self._slot_truth = self._slot_images = self._slot_t = self._action_block = None  # type: ignore[assignment]
        self._u32 = self._i32 = self._u64 = None  # type: ignore[assignment]
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
    """Creates /dev/shm/NAME (0600) laid out for `declaration`, publishes frames with their truth and reads the
    driver's actions.

    lockstep=True: after publish(frame n) the world calls wait_action(n) (TORCS's `written` flag).
    lockstep=False (free-running): the world never waits; latest_action() gives the newest action, if any.
    peer_timeout: seconds without a driver heartbeat before the driver counts as dead (None: pid test only).
    spin: seconds of busy-waiting before a wait sleeps on the futex.
    """

    _role = "world"
    _peer_role = "driver"

    def __init__(self, name: str, declaration: WorldDeclaration, lockstep: bool = True,
                 peer_timeout: float | None = 2.0, *, spin: float = DEFAULT_SPIN):
        layout.check_native_byte_order()
        if not futex.available():
            raise BridgeError("the shared-memory bridge needs Linux futexes (unsupported platform)")
        if not isinstance(declaration, WorldDeclaration):
            raise TypeError("WorldEndpoint needs the world's WorldDeclaration")
        lay = layout.layout_for(declaration, lockstep)
        seg = _create(name, lay.layout_size)
        try:
            lay.write_header(seg.buf)
            seg.i32[_U32["world_pid"]] = os.getpid()
            seg.u64[_U64["world_heartbeat_ns"]] = time.monotonic_ns()
            seg.u32[_U32["world_state"]] = WORLD_RUNNING
            seg.buf[:len(MAGIC)] = np.frombuffer(MAGIC, dtype=np.uint8)   # last: the segment is ready
            link = _Link(seg, "world_state", WORLD_CLOSED, "driver_bell", "world_heartbeat_ns", unlink=True)
        except BaseException:
            seg.unlink()
            seg.close()
            raise
        self.declaration = declaration
        self._peer_heartbeat = _U64["driver_heartbeat_ns"]
        self._seq = 0
        self._setup(seg, lay, link, "world_bell", peer_timeout, spin)
        self._shapes = tuple(c.shape for c in declaration.cameras)
        self._truth_len = len(declaration.truth)

    # --- the driver ------------------------------------------------------------------------------------------------
    def _peer_state(self):
        state = self._u32[_U32["driver_state"]]
        if state == DRIVER_NONE:
            return None, 0
        pid = self._i32[_U32["driver_pid"]]
        return ("left" if state == DRIVER_DETACHED else "attached"), pid

    def _lose(self, message: str, pid: int, orderly: bool = False) -> PeerGone:
        gone = super()._lose(message, pid, orderly)
        gone.finished = orderly and not self._closed and self._u32[_U32["driver_status"]] == STATUS_FINISHED
        if gone.finished:
            gone.args = (f"the driver (pid {pid}) finished the run",)
        return gone

    def _gone_again(self) -> PeerGone:
        again = super()._gone_again()
        again.finished = getattr(self._gone, "finished", False)
        return again

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
    def driver_status(self) -> str:
        """"driving", "finished" (the driver ended the run in order) or "failed"."""
        self._require_open()
        v = self._u32[_U32["driver_status"]]
        return DRIVER_STATUSES[v] if v < len(DRIVER_STATUSES) else f"unknown({v})"

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
    def publish(self, frames, record, t: float = 0.0) -> int:
        """Write the images (one (h, w, c) uint8 array per camera, or a single array for a one-camera world), the
        truth record (float64 in declaration order, or a mapping) and the simulated time t [s] as the next frame;
        return its seq. Never waits. Raises PeerGone when the driver has died or left."""
        self._require_open()
        if isinstance(frames, np.ndarray):
            frames = (frames,)
        shapes = self._shapes
        if len(frames) != len(shapes) or any(
                not isinstance(f, np.ndarray) or f.dtype != np.uint8 or f.shape != shape
                for f, shape in zip(frames, shapes)):
            got = [(getattr(f, "shape", None), str(getattr(f, "dtype", type(f).__name__))) for f in frames]
            raise ValueError(f"frames must be {len(shapes)} uint8 image(s) of shape(s) {list(shapes)}, got {got}")
        if isinstance(record, Mapping) or np.shape(record) != (self._truth_len,):
            record = self.declaration.check_record(record)
        self._check_peer()
        seq = self._seq + 1
        i = seq % SLOT_COUNT
        u64, lock = self._u64, self._slot_lock[i]
        version = u64[lock]
        u64[lock] = version + 1                 # odd: being written
        u64[self._slot_seq[i]] = seq
        self._slot_t[i][0] = t
        self._slot_truth[i][:] = record
        for dst, src in zip(self._slot_images[i], frames):
            np.copyto(dst, src)
        u64[lock] = version + 2                 # even: complete
        u64[_U64["frame_seq"]] = seq
        self._seq = seq
        self._link.ring()
        return seq

    # --- actions ---------------------------------------------------------------------------------------------------
    def _read_action(self):
        """(seq, action + estimate float64 copy), or None while the driver is in the middle of a write."""
        u64, lock, aseq = self._u64, self._action_lock, self._action_seq
        for _ in range(1000):
            version = u64[lock]
            if version & 1:
                continue
            seq = u64[aseq]
            values = self._action_block.copy()
            if u64[lock] == version:
                return seq, values
        return None

    def _message(self, seq: int, values: np.ndarray) -> ActionMsg:
        n = self._n_action
        return ActionMsg(int(seq), values[:n], values[n:])

    def wait_action(self, seq: int, timeout: float | None = None) -> ActionMsg:
        """Lock-step: wait for the driver's action for frame `seq` (or a later one) and return it.

        BridgeTimeout after `timeout` seconds, PeerGone when the driver died or left (`finished` set when it
        ended the run in order)."""
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

    # --- the end ---------------------------------------------------------------------------------------------------
    def end(self, reason: str = "finished") -> None:
        """Close the run, telling the driver why: "finished", "host lost", "interrupted", "driver finished" or
        "error" (a driver reads it as DriverEndpoint.end_reason)."""
        if self._closed:
            return
        if reason not in END_REASONS[1:]:
            raise ValueError(f"end reason must be one of {', '.join(END_REASONS[1:])}, got {reason!r}")
        self._u32[_U32["end_reason"]] = END_REASONS.index(reason)
        self.close()


def _create(name: str, size: int) -> Segment:
    """Create the segment; a leftover of a dead world under the same name is removed first."""
    validate_name(name)
    for _attempt in range(3):
        try:
            return Segment.create(name, size)
        except FileExistsError:
            problem = _stale_or_busy(name)
            if problem is not None:
                raise Refused(problem) from None
    raise Refused(f"cannot create shared memory {name!r}: the name keeps being taken")


def _stale_or_busy(name: str) -> str | None:
    """Remove /dev/shm/NAME when it is a bridge segment whose world is dead (None); else why it must stay."""
    seg = Segment.open(name, FIXED_SIZE)
    if seg is None:
        return None if not os.path.exists(shm_path(name)) else \
            f"shared memory {name!r} already exists (being created, or not a bridge segment)"
    try:
        if bytes(seg.buf[:len(MAGIC)]) != MAGIC:
            return (f"shared memory {name!r} already exists and is not a bridge segment "
                    f"(remove {shm_path(name)} if it is stale)")
        pid, closed = world_of(seg)
        if not closed and pid_alive(pid):
            return f"shared memory {name!r} is in use by another world process (pid {pid})"
        seg.unlink()
        return None
    finally:
        seg.close()


def world_of(seg: Segment) -> tuple[int, bool]:
    """(world pid, closed?) of a bridge segment; one of another protocol version reads as closed (pid 0): its
    fields are not ours to read, and no world of this version can be using it."""
    if seg.u32[_U32["version"]] == VERSION:
        return int(seg.i32[_U32["world_pid"]]), seg.u32[_U32["world_state"]] == WORLD_CLOSED
    return 0, True


def reclaim(prefix: str) -> list[str]:
    """Remove the bridge segments named PREFIX* whose world process is dead or closed (left by a run killed
    with SIGKILL, whose peer died too); returns the names removed. Segments of live worlds stay."""
    removed: list[str] = []
    try:
        entries = os.listdir(SHM_DIR)
    except OSError:
        return removed
    for entry in entries:
        if not entry.startswith(prefix):
            continue
        try:
            seg = Segment.open(entry, FIXED_SIZE)
        except BridgeError:
            continue
        if seg is None:
            continue
        try:
            if bytes(seg.buf[:len(MAGIC)]) != MAGIC:
                continue
            pid, closed = world_of(seg)
            if closed or not pid_alive(pid):
                if seg.unlink():
                    removed.append(entry)
        finally:
            seg.close()
    return removed


# --- the driver side -----------------------------------------------------------------------------------------------
class DriverEndpoint(_Endpoint):
    """Attaches to the world's segment, takes frames and sends actions.

    The world's declaration comes from the header (`declaration`, `layout`); `require(...)` checks that it offers
    what this driver needs. attach_timeout: seconds to wait for the world to create the segment. peer_timeout:
    seconds without a world heartbeat before the world counts as dead (None: pid test only). Only one driver may
    attach at a time.
    """

    _role = "driver"
    _peer_role = "world"

    def __init__(self, name: str, attach_timeout: float = DEFAULT_ATTACH_TIMEOUT,
                 peer_timeout: float | None = 2.0, *, spin: float = DEFAULT_SPIN):
        layout.check_native_byte_order()
        if not futex.available():
            raise BridgeError("the shared-memory bridge needs Linux futexes (unsupported platform)")
        name = validate_name(name)
        seg, lay = _attach(name, attach_timeout)
        try:
            try:
                declaration = lay.declaration_object()
            except DeclarationError as e:
                raise ProtocolMismatch(f"shared memory {name!r}: {e}") from None
            try:
                fcntl.flock(seg.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                pid = seg.i32[_U32["driver_pid"]]
                raise Refused(f"shared memory {name!r} already has a driver (pid {pid})") from None
            if seg.u32[_U32["driver_state"]] != DRIVER_NONE:   # one driver per run: the world is ending this one
                pid = seg.i32[_U32["driver_pid"]]
                raise Refused(f"shared memory {name!r} has already served a driver (pid {pid}) in this run; "
                              "the world ends the run when its driver leaves") from None
            seg.i32[_U32["driver_pid"]] = os.getpid()
            seg.u64[_U64["driver_heartbeat_ns"]] = time.monotonic_ns()
            seg.u32[_U32["driver_state"]] = DRIVER_ATTACHED
            link = _Link(seg, "driver_state", DRIVER_DETACHED, "world_bell", "driver_heartbeat_ns", unlink=False)
            link.ring()
        except BaseException:
            seg.close()
            raise
        self.declaration = declaration
        self._parent = os.getppid()   # the world, when it started this driver
        self._peer_heartbeat = _U64["world_heartbeat_ns"]
        self._last_seq = 0
        self._n_estimate = len(lay.estimate)
        self._end_reason = "none"
        self.discarded_copies = 0   # copies thrown away because the world rewrote the slot meanwhile
        self._setup(seg, lay, link, "driver_bell", peer_timeout, spin)

    def _peer_state(self):
        if self._u32[_U32["world_state"]] == WORLD_CLOSED:
            return None, 0   # the world ended the run in order: wait_frame returns None, actions go nowhere
        return "attached", int(self._i32[_U32["world_pid"]])

    def _before_close(self) -> None:
        self._end_reason = self._stored_end_reason()   # what end_reason answers once the views are gone
        world = int(self._i32[_U32["world_pid"]])
        # a world that started this driver and died is gone once this process has another parent, even while its
        # exit is still under way (a parent-death signal arrives then)
        orphaned = world == self._parent and os.getppid() != world
        if self._u32[_U32["world_state"]] != WORLD_CLOSED and (orphaned or not pid_alive(world)):
            self._link.unlink = True   # the world died unnoticed: its segment would be left behind

    @property
    def world_pid(self) -> int:
        self._require_open()
        return int(self._i32[_U32["world_pid"]])

    @property
    def world(self) -> str:
        return self.layout.world

    @property
    def end_reason(self) -> str:
        """Why the world ended the run ("none" while it runs): "finished", "host lost", "interrupted",
        "driver finished" or "error"."""
        if self._closed:
            return self._end_reason
        return self._stored_end_reason()

    def _stored_end_reason(self) -> str:
        v = self._u32[_U32["end_reason"]]
        return END_REASONS[v] if v < len(END_REASONS) else f"unknown({v})"

    @property
    def last_seq(self) -> int:
        """The seq of the newest frame this driver has taken (0: none yet)."""
        return self._last_seq

    def require(self, world: str | None = None, cameras: Sequence | None = None, truth: Sequence[str] = (),
                action: Sequence[str] | None = None, estimate: Sequence[str] = (), modes: Sequence[str] = ()) -> None:
        """Check that the world offers what this driver needs, else ProtocolMismatch in one line: its name, camera
        names with (height, width) ((name, None) accepts any size), truth fields, the exact action, estimate
        fields and behavioural modes. Fields are found by name; their order is the header's."""
        lay, problems = self.layout, []
        if world is not None and lay.world != world:
            problems.append(f"it serves world {lay.world!r}, not {world!r}")
        cams = {c.name: (c.height, c.width) for c in lay.cameras}
        for cam in cameras or ():
            cname, size = (cam, None) if isinstance(cam, str) else cam
            if cname not in cams:
                problems.append(f"it has no camera {cname!r} (cameras: {', '.join(cams)})")
            elif size is not None and tuple(size) != cams[cname]:
                problems.append(f"camera {cname!r} is {cams[cname][1]}x{cams[cname][0]}, not {size[1]}x{size[0]}")
        have = {n for n, _ in lay.truth}
        missing = [n for n in truth if n not in have]
        if missing:
            problems.append(f"its truth record lacks {', '.join(missing)}")
        names = tuple(a[0] for a in lay.action)
        if action is not None and tuple(action) != names:
            problems.append(f"its action is ({', '.join(names)}), not ({', '.join(action)})")
        have = {n for n, _ in lay.estimate}
        missing = [n for n in estimate if n not in have]
        if missing:
            problems.append(f"its estimate has no place for {', '.join(missing)}")
        missing = [m for m in modes if m not in lay.modes]
        if missing:
            problems.append(f"it has no behavioural mode {', '.join(missing)}")
        if problems:
            raise ProtocolMismatch(f"shared memory {self.name!r} does not fit this driver: {'; '.join(problems)}")

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
                images = tuple(img.copy() for img in self._slot_images[i])
                record = self._slot_truth[i].copy()
                t = float(self._slot_t[i][0])
                if u64[lock] == version:
                    self._last_seq = seq
                    u64[_U64["driver_seen_seq"]] = seq
                    u32 = self._u32
                    mode = u32[_U32["driver_mode"]]
                    return FrameMsg(int(seq), images, record, t, bool(u32[_U32["paused"]]),
                                    DRIVER_MODES[mode] if mode < len(DRIVER_MODES) else f"unknown({mode})",
                                    int(u32[_U32["behaviour"]]))
                self.discarded_copies += 1
            seq = u64[_U64["frame_seq"]]   # the world moved on while we copied: take the newer frame
        return _NOTHING

    def wait_frame(self, timeout: float | None = None) -> FrameMsg | None:
        """The next frame (lock-step) or the newest one (free-running); None once the world closed the run
        (`end_reason` says why).

        BridgeTimeout after `timeout` seconds, PeerGone when the world process died."""
        self._require_open()
        return self._wait(self._take_frame, timeout, "no frame from the world")

    # --- actions ---------------------------------------------------------------------------------------------------
    def send_action(self, seq: int, action, estimate=None) -> None:
        """Answer frame `seq` with `action` (the world's action values, in header order; an object with
        `as_array()` is accepted) and the estimate (NaN: none)."""
        self._require_open()
        self._check_peer()
        a = action.as_array() if hasattr(action, "as_array") else np.asarray(action, dtype=np.float64)
        if a.shape != (self._n_action,):
            names = ", ".join(x[0] for x in self.layout.action)
            raise ValueError(f"action must hold {self._n_action} values ({names}), got shape {a.shape}")
        if estimate is None:
            est = np.full(self._n_estimate, np.nan)
        else:
            est = np.asarray(estimate, dtype=np.float64)
            if est.shape != (self._n_estimate,):
                raise ValueError(f"estimate must hold {self._n_estimate} values (the header's estimate names), "
                                 f"got shape {est.shape}")
        u64, lock = self._u64, self._action_lock
        version = u64[lock]
        u64[lock] = version + 1
        u64[self._action_seq] = int(seq)
        block = self._action_block
        block[:self._n_action] = a
        block[self._n_action:] = est
        u64[lock] = version + 2
        self._link.ring()

    def finish(self, failed: bool = False) -> None:
        """Leave the run in order: the world ends it as "driver finished" (status "failed" with failed=True)."""
        if self._closed:
            return
        self._u32[_U32["driver_status"]] = STATUS_FAILED if failed else STATUS_FINISHED
        self.close()


def _attach(name: str, timeout: float) -> tuple[Segment, Layout]:
    """Open the world's segment, waiting up to `timeout` s for it to appear, and check its header.

    A zero magic means "not ready yet" (keep waiting); any other magic than "DSBRIDGE" means "not ours" (refuse)."""
    deadline = time.monotonic() + timeout
    delay = 0.001
    while True:
        seg = Segment.open(name, FIXED_SIZE)
        if seg is not None:
            try:
                magic = bytes(seg.buf[:len(MAGIC)])
                if magic == MAGIC:
                    result = _check_header(seg)
                    if isinstance(result, Layout):
                        return seg, result
                    if result != "stale":
                        raise ProtocolMismatch(result)
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


def _byteswap32(v: int) -> int:
    return int.from_bytes(int(v).to_bytes(4, "little"), "big")


def _check_header(seg: Segment):
    """The Layout when the header is a consistent version-2 header, "stale" for a dead world's leftover (removed),
    else the mismatch in one line."""
    u32, name = seg.u32, seg.name
    # the version word is at offset 8 in every version; byte_order moved (offset 60 in version 1, 24 in 2), so
    # it is read only once the version says where it is
    version = u32[_U32["version"]]
    if version != VERSION:
        if _byteswap32(version) in (1, VERSION):
            return f"shared memory {name!r} was written with the other byte order"
        return f"shared memory {name!r} has protocol version {version}, this driver speaks {VERSION}"
    if u32[_U32["byte_order"]] != layout.BYTE_ORDER_MARK:
        return f"shared memory {name!r} was written with the other byte order"
    try:
        lay = Layout.read(seg.buf)
    except ValueError as e:
        return f"shared memory {name!r} has a corrupt header ({e})"
    problems = lay.mismatches(seg.buf)
    declared = int(seg.u64[_U64["layout_size"]])
    if problems or seg.size < declared:
        return (f"shared memory {name!r} declares a layout of {declared} bytes ({seg.size} mapped) that its own "
                f"description contradicts" + (f": {', '.join(problems)}" if problems else ""))
    pid = seg.i32[_U32["world_pid"]]
    if u32[_U32["world_state"]] == WORLD_CLOSED or not pid_alive(pid):
        unlink_if_same(seg.path, seg.dev, seg.ino)   # a dead world's leftover: remove it, wait for a new one
        return "stale"
    return lay
