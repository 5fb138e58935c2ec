"""The one owner of the bridge's binary layout, protocol version 2.

Everything another program needs to read or write the segment is defined here once: a table of the control
block's fixed fields (CONTROL_FIELDS), the entries of the two description tables (CAMERA_FIELDS, NAME_FIELDS),
the slot header (SLOT_FIELDS), and `Layout`, which places the parts whose size depends on the world: the camera
table, the name table, the declaration text, the action record and the images. From these this module derives the
numpy dtypes, the C declarations that docs/shm-protocol.md shows (``python -m shm_bridge.layout`` prints them; a
test checks the document against them) and the size checks. Byte order is little-endian; every field is naturally
aligned; the futex words are 4-byte aligned 32-bit words.

Segment = control block (`header_size` bytes: fixed fields, camera table, name table, declaration, action record)
+ SLOT_COUNT frame slots of `slot_size` bytes. Slot i starts at header_size + i * slot_size; frame number `seq`
(1, 2, 3, ...) lives in slot ``seq % SLOT_COUNT``. A slot holds its seqlock, seq, the simulated time, the truth
record (float64 x truth_len, the declaration's truth fields in order) and then one image per camera, each at its
camera's offset from the start of the slot.

The header describes the world (protocol version 2): its name, its cameras and their sizes, and the names (with
units, and for the action its range and neutral value) of every value of the truth record, the estimate and the
action, so a client in C finds a field by name. The declaration's JSON text follows, for clients that want every
detail (normalisation, modes); Python drivers rebuild the WorldDeclaration from it.
"""
from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass

import numpy as np

from core import worlds
from core.declaration import DeclarationError, WorldDeclaration

# --- constants of protocol version 2 -------------------------------------------------------------------------------
MAGIC = b"DSBRIDGE"            # 8 bytes at offset 0, written last by the world when the segment is ready
VERSION = 2
BYTE_ORDER_MARK = 0x01020304   # written as a native uint32; a reader with the other byte order sees 0x04030201
FIXED_SIZE = 320               # bytes of the control block's fixed fields; the camera table follows
SLOT_COUNT = 2                 # frame slots (double buffer, each guarded by its own seqlock)
ALIGN = 64                     # tables, the action record, slots and images start on a cache line
CAMERA_ENTRY = 64              # bytes of one camera table entry
NAME_ENTRY = 64                # bytes of one name table entry
NAME_BYTES = 32                # a name: ASCII, NUL-padded (at most 31 characters)
UNIT_BYTES = 8                 # a unit: ASCII, NUL-padded
MAX_CAMERAS = 8
MAX_VALUES = 4096              # per record (truth, estimate, action)
MAX_MODES = 32
MAX_DECLARATION = 1 << 16      # bytes of the declaration's JSON text

MODE_LOCKSTEP = 0
MODE_FREE_RUNNING = 1

WORLD_INIT, WORLD_RUNNING, WORLD_CLOSED = 0, 1, 2            # world_state
DRIVER_NONE, DRIVER_ATTACHED, DRIVER_DETACHED = 0, 1, 2      # driver_state
DRIVER_MODE_NETWORK, DRIVER_MODE_MANUAL = 0, 1               # driver_mode: who drives
DRIVER_MODES = ("network", "manual")
# end_reason: why the world closed the run (stored before world_state = closed)
END_REASONS = ("none", "finished", "host lost", "interrupted", "driver finished", "error")
END_NONE, END_FINISHED, END_HOST_LOST, END_INTERRUPTED, END_DRIVER_FINISHED, END_ERROR = range(6)
# driver_status: how the driver leaves (stored before driver_state = detached)
DRIVER_STATUSES = ("driving", "finished", "failed")
STATUS_DRIVING, STATUS_FINISHED, STATUS_FAILED = range(3)


@dataclass(frozen=True)
class Field:
    name: str
    ctype: str        # C type of one element
    count: int        # elements (1: a scalar)
    offset: int       # bytes from the start of its block
    doc: str
    writer: str = ""  # who stores it: "world (once)", "world", "driver" or "either"

    @property
    def size(self) -> int:
        return _CTYPES[self.ctype][1] * self.count

    @property
    def numpy(self) -> str:
        return _CTYPES[self.ctype][0]


_CTYPES = {"uint8_t": ("<u1", 1), "char": ("S1", 1), "uint32_t": ("<u4", 4), "int32_t": ("<i4", 4),
           "uint64_t": ("<u8", 8), "double": ("<f8", 8)}


def _block(writer: str, *rows: tuple[str, str, int, int, str]) -> tuple[Field, ...]:
    return tuple(Field(name, ctype, count, offset, doc, writer=writer) for name, ctype, count, offset, doc in rows)


CONTROL_FIELDS: tuple[Field, ...] = (
    # identity: written once by the world before `magic`, never changed afterwards
    *_block("world (once)",
            ("magic", "uint8_t", 8, 0, '"DSBRIDGE", stored last, when the segment is ready'),
            ("version", "uint32_t", 1, 8, "protocol version (2)"),
            ("header_size", "uint32_t", 1, 12, "bytes before slot 0"),
            ("layout_size", "uint64_t", 1, 16, "bytes of the whole segment"),
            ("byte_order", "uint32_t", 1, 24, "0x01020304 in the writer's byte order"),
            ("mode", "uint32_t", 1, 28, "0 = lock-step, 1 = free-running"),
            ("world", "char", NAME_BYTES, 32, "world name, NUL-padded (e.g. \"highway\")"),
            ("slot_count", "uint32_t", 1, 64, "frame slots (2)"),
            ("slot_size", "uint32_t", 1, 68, "bytes per slot"),
            ("slot_header_size", "uint32_t", 1, 72, "bytes of a slot before the first image"),
            ("camera_count", "uint32_t", 1, 76, "images per frame (entries of the camera table)"),
            ("truth_len", "uint32_t", 1, 80, "float64 values in a truth record"),
            ("estimate_len", "uint32_t", 1, 84, "float64 values in an estimate"),
            ("action_len", "uint32_t", 1, 88, "float64 values in an action"),
            ("mode_count", "uint32_t", 1, 92, "behavioural modes (0: the world has none)"),
            ("cameras_offset", "uint32_t", 1, 96, "offset of the camera table (64-byte entries)"),
            ("names_offset", "uint32_t", 1, 100, "offset of the name table (64-byte entries)"),
            ("action_offset", "uint32_t", 1, 104, "offset of the action record"),
            ("step_us", "uint32_t", 1, 108, "simulated time of one world step [us]"),
            ("declaration_offset", "uint32_t", 1, 112, "offset of the declaration (JSON, UTF-8)"),
            ("declaration_size", "uint32_t", 1, 116, "bytes of the declaration")),
    # the world's cache line: stored by the world only
    *_block("world",
            ("driver_bell", "uint32_t", 1, 128, "futex word the driver sleeps on"),
            ("world_state", "uint32_t", 1, 132, "0 = initialising, 1 = running, 2 = closed"),
            ("world_pid", "int32_t", 1, 136, "process id of the world"),
            ("end_reason", "uint32_t", 1, 140, "why the run ended: 0 = not yet, 1 = finished, 2 = host lost, "
                                               "3 = interrupted, 4 = driver finished, 5 = error"),
            ("world_heartbeat_ns", "uint64_t", 1, 144, "CLOCK_MONOTONIC [ns], refreshed every <= 200 ms"),
            ("frame_seq", "uint64_t", 1, 152, "seq of the newest complete frame (0: none yet)")),
    # the driver's cache line: stored by the driver only
    *_block("driver",
            ("world_bell", "uint32_t", 1, 192, "futex word the world sleeps on"),
            ("driver_state", "uint32_t", 1, 196, "0 = none, 1 = attached, 2 = detached"),
            ("driver_pid", "int32_t", 1, 200, "process id of the driver"),
            ("driver_status", "uint32_t", 1, 204, "0 = driving, 1 = finished (ends the run in order), 2 = failed"),
            ("driver_heartbeat_ns", "uint64_t", 1, 208, "CLOCK_MONOTONIC [ns], refreshed every <= 200 ms"),
            ("driver_seen_seq", "uint64_t", 1, 216, "seq of the newest frame the driver has taken")),
    # shared flags: stored whole by either side, which then rings the other side's bell
    *_block("either",
            ("paused", "uint32_t", 1, 256, "1 = paused"),
            ("driver_mode", "uint32_t", 1, 260, "who drives: 0 = network, 1 = manual/expert"),
            ("behaviour", "uint32_t", 1, 264, "behavioural mode: index into the mode names")),
)

CAMERA_FIELDS: tuple[Field, ...] = _block(
    "world (once)",
    ("name", "char", NAME_BYTES, 0, "camera name, NUL-padded"),
    ("height", "uint32_t", 1, 32, "image rows"),
    ("width", "uint32_t", 1, 36, "image columns"),
    ("channels", "uint32_t", 1, 40, "3: R, G, B"),
    ("offset", "uint32_t", 1, 44, "offset of the image from the start of a slot"),
    ("size", "uint32_t", 1, 48, "height * width * channels bytes"),
)

NAME_FIELDS: tuple[Field, ...] = _block(
    "world (once)",
    ("name", "char", NAME_BYTES, 0, "field name, NUL-padded"),
    ("unit", "char", UNIT_BYTES, 32, "unit, NUL-padded (e.g. \"m\", \"rad\", \"m/s\", \"0/1\")"),
    ("low", "double", 1, 40, "action: lowest value (NaN elsewhere)"),
    ("high", "double", 1, 48, "action: highest value (NaN elsewhere)"),
    ("neutral", "double", 1, 56, "action: the value meaning 'nothing' (NaN elsewhere)"),
)

SLOT_FIELDS: tuple[Field, ...] = _block(
    "world",   # under the slot's seqlock `lock`
    ("lock", "uint64_t", 1, 0, "seqlock: odd while the slot is being written"),
    ("seq", "uint64_t", 1, 8, "seq of the frame in this slot"),
    ("t", "double", 1, 16, "simulated time of the frame [s]"),
    # truth: double[truth_len] at offset SLOT_TRUTH; images at slot_header_size + ...
)
SLOT_TRUTH = 24                # offset of the truth record inside a slot

ACTION_FIELDS: tuple[Field, ...] = _block(
    "driver",  # at action_offset, under the seqlock `action_lock`
    ("action_lock", "uint64_t", 1, 0, "seqlock: odd while the record is being written"),
    ("action_seq", "uint64_t", 1, 8, "seq of the frame this action answers (0: none yet)"),
    # action: double[action_len] at offset 16, then estimate: double[estimate_len]
)
ACTION_VALUES = 16             # offset of the action values inside the action record

FUTEX_WORDS = ("driver_bell", "world_bell")


def _offsets(fields) -> dict[str, int]:
    return {f.name: f.offset for f in fields}


CONTROL: dict[str, Field] = {f.name: f for f in CONTROL_FIELDS}
OFFSET: dict[str, int] = _offsets(CONTROL_FIELDS)
SLOT_OFFSET: dict[str, int] = _offsets(SLOT_FIELDS)
ACTION_OFFSET: dict[str, int] = _offsets(ACTION_FIELDS)


def _dtype(fields, itemsize: int) -> np.dtype:
    return np.dtype({"names": [f.name for f in fields],
                     "formats": [(f.numpy, (f.count,)) if f.count > 1 and f.ctype != "char" else
                                 (f"S{f.count}" if f.ctype == "char" else f.numpy) for f in fields],
                     "offsets": [f.offset for f in fields], "itemsize": itemsize})


CONTROL_DTYPE = _dtype(CONTROL_FIELDS, FIXED_SIZE)
CAMERA_DTYPE = _dtype(CAMERA_FIELDS, CAMERA_ENTRY)
NAME_DTYPE = _dtype(NAME_FIELDS, NAME_ENTRY)


def _validate(fields, size: int, block: str) -> None:
    end = 0
    for f in sorted(fields, key=lambda f: f.offset):
        align = _CTYPES[f.ctype][1]
        if f.offset % align:
            raise AssertionError(f"{block}.{f.name} at {f.offset} is not {align}-byte aligned")
        if f.offset < end:
            raise AssertionError(f"{block}.{f.name} overlaps the field before it")
        end = f.offset + f.size
    if end > size:
        raise AssertionError(f"{block} needs {end} bytes, has {size}")


_validate(CONTROL_FIELDS, FIXED_SIZE, "control")
_validate(CAMERA_FIELDS, CAMERA_ENTRY, "camera")
_validate(NAME_FIELDS, NAME_ENTRY, "name")
_validate(SLOT_FIELDS, SLOT_TRUTH, "slot")
_validate(ACTION_FIELDS, ACTION_VALUES, "action")
for _w in FUTEX_WORDS:
    assert CONTROL[_w].ctype == "uint32_t" and CONTROL[_w].offset % 4 == 0


def _align(n: int) -> int:
    return -(-n // ALIGN) * ALIGN


# --- the layout of one world's segment -----------------------------------------------------------------------------
@dataclass(frozen=True)
class CameraSlot:
    name: str
    height: int
    width: int
    channels: int
    offset: int      # from the start of a slot
    size: int


@dataclass(frozen=True)
class Layout:
    """Where everything lies in a segment for one world (and what its header says)."""

    world: str
    cameras: tuple[CameraSlot, ...]
    truth: tuple[tuple[str, str], ...]           # (name, unit)
    estimate: tuple[tuple[str, str], ...]
    action: tuple[tuple[str, str, float, float, float], ...]   # (name, unit, low, high, neutral)
    modes: tuple[str, ...]
    declaration: bytes                           # the declaration's JSON text
    step_us: int
    lockstep: bool = True

    # --- derived offsets -----------------------------------------------------------------------------------------
    @property
    def cameras_offset(self) -> int:
        return FIXED_SIZE

    @property
    def names_offset(self) -> int:
        return self.cameras_offset + CAMERA_ENTRY * len(self.cameras)

    @property
    def name_count(self) -> int:
        return len(self.truth) + len(self.estimate) + len(self.action) + len(self.modes)

    @property
    def declaration_offset(self) -> int:
        return self.names_offset + NAME_ENTRY * self.name_count

    @property
    def action_offset(self) -> int:
        return _align(self.declaration_offset + len(self.declaration))

    @property
    def action_record_size(self) -> int:
        return ACTION_VALUES + 8 * (len(self.action) + len(self.estimate))

    @property
    def header_size(self) -> int:
        return _align(self.action_offset + self.action_record_size)

    @property
    def slot_header_size(self) -> int:
        return _align(SLOT_TRUTH + 8 * len(self.truth))

    @property
    def slot_size(self) -> int:
        end = self.slot_header_size
        for c in self.cameras:
            end = max(end, c.offset + c.size)
        return _align(end)

    @property
    def layout_size(self) -> int:
        return self.header_size + SLOT_COUNT * self.slot_size

    def slot_offset(self, index: int) -> int:
        return self.header_size + index * self.slot_size

    def header_values(self) -> dict:
        """The fixed header fields (all but magic and the run-time words)."""
        return {"version": VERSION, "header_size": self.header_size, "layout_size": self.layout_size,
                "byte_order": BYTE_ORDER_MARK, "mode": MODE_LOCKSTEP if self.lockstep else MODE_FREE_RUNNING,
                "world": self.world.encode("ascii"), "slot_count": SLOT_COUNT, "slot_size": self.slot_size,
                "slot_header_size": self.slot_header_size, "camera_count": len(self.cameras),
                "truth_len": len(self.truth), "estimate_len": len(self.estimate), "action_len": len(self.action),
                "mode_count": len(self.modes), "cameras_offset": self.cameras_offset,
                "names_offset": self.names_offset, "action_offset": self.action_offset, "step_us": self.step_us,
                "declaration_offset": self.declaration_offset, "declaration_size": len(self.declaration)}

    # --- writing and reading the description ----------------------------------------------------------------------
    def write_header(self, buf: np.ndarray) -> None:
        """Store every description field (not magic) into the segment's bytes `buf`."""
        header = buf[:FIXED_SIZE].view(CONTROL_DTYPE)[0]
        for key, value in self.header_values().items():
            header[key] = value
        cams = buf[self.cameras_offset:self.names_offset].view(CAMERA_DTYPE)
        for entry, c in zip(cams, self.cameras):
            entry["name"] = c.name.encode("ascii")
            for k in ("height", "width", "channels", "offset", "size"):
                entry[k] = getattr(c, k)
        names = buf[self.names_offset:self.declaration_offset].view(NAME_DTYPE)
        rows = [(n, u, math.nan, math.nan, math.nan) for n, u in self.truth + self.estimate]
        rows += list(self.action) + [(m, "", math.nan, math.nan, math.nan) for m in self.modes]
        for entry, (n, u, lo, hi, neutral) in zip(names, rows):
            entry["name"], entry["unit"] = n.encode("ascii"), u.encode("ascii")[:UNIT_BYTES]
            entry["low"], entry["high"], entry["neutral"] = lo, hi, neutral
        start = self.declaration_offset
        buf[start:start + len(self.declaration)] = np.frombuffer(self.declaration, dtype=np.uint8)

    @classmethod
    def read(cls, buf: np.ndarray) -> Layout:
        """The layout a version-2 header in `buf` describes (the caller checked magic, version and byte order).
        Raises ValueError when the header contradicts itself or the buffer."""
        h = buf[:FIXED_SIZE].view(CONTROL_DTYPE)[0]
        counts = {k: int(h[k]) for k in ("camera_count", "truth_len", "estimate_len", "action_len", "mode_count")}
        if not 1 <= counts["camera_count"] <= MAX_CAMERAS or counts["mode_count"] > MAX_MODES or \
                any(counts[k] > MAX_VALUES for k in ("truth_len", "estimate_len", "action_len")):
            raise ValueError(f"implausible record sizes {counts}")
        dsize, doff = int(h["declaration_size"]), int(h["declaration_offset"])
        names_off, cams_off = int(h["names_offset"]), int(h["cameras_offset"])
        if cams_off != FIXED_SIZE or dsize > MAX_DECLARATION or doff + dsize > len(buf) or \
                names_off + NAME_ENTRY * (counts["truth_len"] + counts["estimate_len"] + counts["action_len"]
                                          + counts["mode_count"]) > len(buf):
            raise ValueError("the description tables lie outside the header")
        cams = buf[cams_off:cams_off + CAMERA_ENTRY * counts["camera_count"]].view(CAMERA_DTYPE)
        cameras = tuple(CameraSlot(_text(e["name"]), int(e["height"]), int(e["width"]), int(e["channels"]),
                                   int(e["offset"]), int(e["size"])) for e in cams)
        n_names = sum(counts[k] for k in ("truth_len", "estimate_len", "action_len", "mode_count"))
        names = buf[names_off:names_off + NAME_ENTRY * n_names].view(NAME_DTYPE)
        rows = [(_text(e["name"]), _text(e["unit"]), float(e["low"]), float(e["high"]), float(e["neutral"]))
                for e in names]
        t, e, a = counts["truth_len"], counts["estimate_len"], counts["action_len"]
        layout = cls(world=_text(h["world"]), cameras=cameras, truth=tuple(r[:2] for r in rows[:t]),
                     estimate=tuple(r[:2] for r in rows[t:t + e]), action=tuple(rows[t + e:t + e + a]),
                     modes=tuple(r[0] for r in rows[t + e + a:]),
                     declaration=bytes(buf[doff:doff + dsize]), step_us=int(h["step_us"]),
                     lockstep=int(h["mode"]) == MODE_LOCKSTEP)
        return layout

    def mismatches(self, buf: np.ndarray) -> list[str]:
        """What the stored header says differently from this layout's own derivation (empty: consistent)."""
        h = buf[:FIXED_SIZE].view(CONTROL_DTYPE)[0]
        out = []
        for key, want in self.header_values().items():
            have = h[key]
            if key == "world":
                continue
            if int(have) != int(want):
                out.append(f"{key} {int(have)} (expected {int(want)})")
        expect_off = self.slot_header_size
        for c in self.cameras:
            if c.offset != expect_off or c.size != c.height * c.width * c.channels:
                out.append(f"camera {c.name} at offset {c.offset} with {c.size} bytes (expected {expect_off}, "
                           f"{c.height * c.width * c.channels})")
            expect_off = _align(c.offset + c.size)
        return out

    def declaration_object(self) -> WorldDeclaration:
        """The WorldDeclaration carried in the header (DeclarationError when it is not one)."""
        try:
            obj = json.loads(self.declaration.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError):
            raise DeclarationError("the header's declaration is not JSON") from None
        decl = WorldDeclaration.from_json(obj)
        if decl.truth_names != tuple(n for n, _ in self.truth) or \
                decl.estimate_names != tuple(n for n, _ in self.estimate) or \
                decl.action_names != tuple(a[0] for a in self.action) or \
                decl.camera_names != tuple(c.name for c in self.cameras) or decl.modes != self.modes:
            raise DeclarationError("the header's declaration contradicts its name tables")
        return decl


def _text(raw) -> str:
    return bytes(raw).split(b"\0", 1)[0].decode("ascii", errors="replace")


def layout_for(decl: WorldDeclaration, lockstep: bool = True) -> Layout:
    """The segment layout of a world: images one after another (64-byte aligned) after the slot header."""
    text = json.dumps(decl.to_json(), separators=(",", ":")).encode("utf-8")
    if len(text) > MAX_DECLARATION:
        raise DeclarationError(f"world {decl.name!r}: its declaration is too large for the bridge header")
    truth_len = len(decl.truth)
    at = _align(SLOT_TRUTH + 8 * truth_len)
    cams = []
    for c in decl.cameras:
        cams.append(CameraSlot(c.name, c.height, c.width, c.channels, at, c.size))
        at = _align(at + c.size)
    units = {lab.name: lab.unit for lab in decl.labels}
    estimate = tuple((n, units.get(n.split("+", 1)[0], "")) for n in decl.estimate_names)
    layout = Layout(world=decl.name, cameras=tuple(cams), truth=tuple((q.name, q.unit) for q in decl.truth),
                    estimate=estimate, action=tuple((a.name, a.unit, a.low, a.high, a.neutral) for a in decl.action),
                    modes=decl.modes, declaration=text, step_us=int(round(decl.dt * 1e6)), lockstep=lockstep)
    if layout.slot_size > 0x7FFFFFFF:
        raise DeclarationError(f"world {decl.name!r}: its frames are too large for the bridge")
    return layout


# --- the C view ----------------------------------------------------------------------------------------------------
def _c_members(fields, size: int, prefix: str) -> tuple[list[str], list[str]]:
    lines, asserts, at, pad = [], [], 0, 0
    for f in sorted(fields, key=lambda f: f.offset):
        if f.offset > at:
            lines.append(f"    uint8_t  _pad{pad}[{f.offset - at}];")
            pad += 1
        decl = f"{f.ctype:<8} {f.name}" + (f"[{f.count}]" if f.count > 1 else "") + ";"
        lines.append(f"    {decl:<36}/* {f.offset:>3}: {f.doc} */")
        asserts.append(f"_Static_assert(offsetof({prefix}, {f.name}) == {f.offset}, \"{f.name}\");")
        at = f.offset + f.size
    if size > at:
        lines.append(f"    uint8_t  _pad{pad}[{size - at}];")
    asserts.append(f"_Static_assert(sizeof({prefix}) == {size}, \"size of {prefix}\");")
    return lines, asserts


def _enum(prefix: str, names) -> str:
    return ", ".join(f"{prefix}_{n.upper().replace(' ', '_')} = {i}" for i, n in enumerate(names))


# long but declarative: the header is one C text, in the order docs/shm-protocol.md shows it
def c_header() -> str:
    """The C declarations of protocol version 2, as docs/shm-protocol.md shows them."""
    ctrl, ctrl_asserts = _c_members(CONTROL_FIELDS, FIXED_SIZE, "ds_control")
    cam, cam_asserts = _c_members(CAMERA_FIELDS, CAMERA_ENTRY, "ds_camera")
    name, name_asserts = _c_members(NAME_FIELDS, NAME_ENTRY, "ds_name")
    slot, slot_asserts = _c_members(SLOT_FIELDS, SLOT_TRUTH, "ds_slot")
    act, act_asserts = _c_members(ACTION_FIELDS, ACTION_VALUES, "ds_action")
    return "\n".join([
        "/* drivestudio shared-memory bridge, protocol version 2 (generated by python -m shm_bridge.layout) */",
        "#ifndef DS_BRIDGE_H",
        "#define DS_BRIDGE_H",
        "#include <stddef.h>",
        "#include <stdint.h>",
        "#include <string.h>",
        "",
        f'#define DS_MAGIC            "{MAGIC.decode()}"   /* 8 bytes, no terminating NUL */',
        f"#define DS_VERSION          {VERSION}u",
        f"#define DS_BYTE_ORDER_MARK  0x{BYTE_ORDER_MARK:08x}u",
        f"#define DS_FIXED_SIZE       {FIXED_SIZE}u   /* the camera table starts here */",
        f"#define DS_NAME_BYTES       {NAME_BYTES}u",
        f"#define DS_SLOT_TRUTH       {SLOT_TRUTH}u   /* the truth record starts here inside a slot */",
        f"#define DS_ACTION_VALUES    {ACTION_VALUES}u   /* the action values start here inside the action record */",
        f"enum {{ DS_MODE_LOCKSTEP = {MODE_LOCKSTEP}, DS_MODE_FREE_RUNNING = {MODE_FREE_RUNNING} }};",
        f"enum {{ DS_WORLD_INIT = {WORLD_INIT}, DS_WORLD_RUNNING = {WORLD_RUNNING}, "
        f"DS_WORLD_CLOSED = {WORLD_CLOSED} }};",
        f"enum {{ DS_DRIVER_NONE = {DRIVER_NONE}, DS_DRIVER_ATTACHED = {DRIVER_ATTACHED}, "
        f"DS_DRIVER_DETACHED = {DRIVER_DETACHED} }};",
        f"enum {{ DS_DRIVER_MODE_NETWORK = {DRIVER_MODE_NETWORK}, DS_DRIVER_MODE_MANUAL = {DRIVER_MODE_MANUAL} }};",
        f"enum {{ {_enum('DS_END', END_REASONS)} }};",
        f"enum {{ {_enum('DS_STATUS', DRIVER_STATUSES)} }};",
        "",
        "typedef struct ds_control {    /* at offset 0 of the segment */",
        *ctrl,
        "} ds_control;",
        "",
        "typedef struct ds_camera {     /* camera_count entries at cameras_offset */",
        *cam,
        "} ds_camera;",
        "",
        "typedef struct ds_name {       /* truth_len + estimate_len + action_len + mode_count entries at "
        "names_offset */",
        *name,
        "} ds_name;",
        "",
        "typedef struct ds_slot {       /* slot i starts at header_size + i * slot_size */",
        *slot,
        "    /* double truth[truth_len] follows at DS_SLOT_TRUTH; camera k's image at ds_camera[k].offset */",
        "} ds_slot;",
        "",
        "typedef struct ds_action {     /* at action_offset */",
        *act,
        "    /* double action[action_len] follows at DS_ACTION_VALUES, then double estimate[estimate_len] */",
        "} ds_action;",
        "",
        "/* The table that names the values of one record: DS_TRUTH, DS_ESTIMATE, DS_ACTION or DS_MODES. */",
        "enum ds_record { DS_TRUTH = 0, DS_ESTIMATE = 1, DS_ACTION = 2, DS_MODES = 3 };",
        "static inline const ds_name *ds_names(const ds_control *c, enum ds_record r, uint32_t *count) {",
        "    uint32_t n[4] = {c->truth_len, c->estimate_len, c->action_len, c->mode_count}, first = 0;",
        "    for (int i = 0; i < (int)r; i++) first += n[i];",
        "    if (count) *count = n[r];",
        "    return (const ds_name *)((const uint8_t *)c + c->names_offset) + first;",
        "}",
        "/* Index of the value called `name` in record r, or -1: e.g. ds_find(c, DS_TRUTH, \"speed\"). */",
        "static inline int ds_find(const ds_control *c, enum ds_record r, const char *name) {",
        "    uint32_t count;",
        "    const ds_name *t = ds_names(c, r, &count);",
        "    for (uint32_t i = 0; i < count; i++)",
        "        if (strncmp(t[i].name, name, DS_NAME_BYTES) == 0) return (int)i;",
        "    return -1;",
        "}",
        "static inline const ds_camera *ds_cameras(const ds_control *c) {",
        "    return (const ds_camera *)((const uint8_t *)c + c->cameras_offset);",
        "}",
        "",
        *ctrl_asserts,
        *cam_asserts,
        *name_asserts,
        *slot_asserts,
        *act_asserts,
        "",
        "#endif /* DS_BRIDGE_H */",
        "",
    ])


# --- the generated parts of docs/shm-protocol.md -------------------------------------------------------------------
def _markdown_fields(fields) -> str:
    rows = ["| offset | bytes | C type | field | stored by | meaning |", "|---:|---:|---|---|---|---|"]
    for f in sorted(fields, key=lambda f: f.offset):
        ctype = f"{f.ctype}[{f.count}]" if f.count > 1 else f.ctype
        rows.append(f"| {f.offset} | {f.size} | `{ctype}` | `{f.name}` | {f.writer} | {f.doc} |")
    return "\n".join(rows)


def _markdown_world(decl: WorldDeclaration) -> str:
    lay = layout_for(decl)
    rows = [f"**{decl.name}** ({decl.title}): `header_size` {lay.header_size}, `slot_size` {lay.slot_size}, "
            f"`layout_size` {lay.layout_size} bytes; `slot_header_size` {lay.slot_header_size}; "
            f"step {lay.step_us} us.", "",
            "| camera | rows x columns x channels | offset in a slot | bytes |", "|---|---|---:|---:|"]
    rows += [f"| `{c.name}` | {c.height} x {c.width} x {c.channels} | {c.offset} | {c.size} |" for c in lay.cameras]
    rows += ["", "| record | index | name | unit | meaning |", "|---|---:|---|---|---|"]
    meaning = {q.name: q.meaning for q in decl.truth}
    rows += [f"| truth | {i} | `{q.name}` | {q.unit} | {meaning[q.name]} |" for i, q in enumerate(decl.truth)]
    lab = {x.name: x.meaning for x in decl.labels}
    rows += [f"| estimate | {i} | `{n}` | {u} | {lab.get(n.split('+', 1)[0], '')} |"
             for i, (n, u) in enumerate(lay.estimate)]
    rows += [f"| action | {i} | `{a.name}` | [{a.low:g}, {a.high:g}], neutral {a.neutral:g} | {a.meaning} |"
             for i, a in enumerate(decl.action)]
    rows += [f"| mode | {i} | `{m}` | | behavioural mode |" for i, m in enumerate(decl.modes)]
    return "\n".join(rows)


def doc_blocks() -> dict[str, str]:
    """The parts of docs/shm-protocol.md that are generated from this module, by marker name."""
    blocks = {"control-table": _markdown_fields(CONTROL_FIELDS), "camera-table": _markdown_fields(CAMERA_FIELDS),
              "name-table": _markdown_fields(NAME_FIELDS), "slot-table": _markdown_fields(SLOT_FIELDS),
              "action-table": _markdown_fields(ACTION_FIELDS), "c-header": "```c\n" + c_header() + "```"}
    blocks["worlds"] = "\n\n".join(_markdown_world(worlds.get(n)) for n in worlds.names())
    return blocks


def _marker(name: str, end: bool = False) -> str:
    return f"<!-- {'END' if end else 'BEGIN'} GENERATED {name} -->"


def render_doc(text: str) -> str:
    """`text` with every generated block (between its BEGIN/END markers) replaced by the current one."""
    for name, block in doc_blocks().items():
        begin, end = _marker(name), _marker(name, end=True)
        i, j = text.find(begin), text.find(end)
        if i < 0 or j < i:
            raise ValueError(f"the document lacks the markers {begin} ... {end}")
        text = text[:i + len(begin)] + "\n" + block + "\n" + text[j:]
    return text


def check_native_byte_order() -> None:
    if sys.byteorder != "little":
        raise RuntimeError("the shared-memory bridge is defined little-endian; this machine is big-endian")


def main(argv: list[str] | None = None) -> int:
    """python -m shm_bridge.layout [--check DOC | --update DOC]: print the C header, or check/refresh a document's
    generated blocks (docs/shm-protocol.md)."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) == 2 and args[0] in ("--check", "--update"):
        with open(args[1], encoding="utf-8") as f:
            text = f.read()
        fresh = render_doc(text)
        if args[0] == "--update":
            with open(args[1], "w", encoding="utf-8") as f:
                f.write(fresh)
            return 0
        if fresh != text:
            print(f"{args[1]}: generated blocks are out of date (run python -m shm_bridge.layout --update)",
                  file=sys.stderr)
            return 1
        return 0
    if args:
        print("usage: python -m shm_bridge.layout [--check DOC | --update DOC]", file=sys.stderr)
        return 2
    print(c_header(), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
