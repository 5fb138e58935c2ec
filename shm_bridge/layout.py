"""The one owner of the bridge's binary layout (protocol version 1) and of the truth record.

Everything another program needs to read or write the segment is defined here once, as a table of fields with
fixed byte offsets. From it this module derives the numpy structured dtypes, the C struct that
docs/shm-protocol.md shows (``python -m shm_bridge.layout`` prints it; a test checks the document against it),
and the size/offset checks. Byte order is little-endian (the native order of x86-64 and aarch64 Linux); every
field is naturally aligned, and the futex words are 4-byte aligned 32-bit words.

Segment = control block (CONTROL_SIZE bytes) + SLOT_COUNT frame slots of `slot_size(frame_size)` bytes each.
Slot i starts at CONTROL_SIZE + i * slot_size; frame number `seq` (1, 2, 3, ...) lives in slot ``seq % SLOT_COUNT``.

The truth record (TRUTH_FIELDS, float64) travels with every frame:
  the 14 indicators in canonical order (shm_bridge.vocabulary.INDICATORS; m, rad, 0/1 for `fast`), then
  lanes_left   lanes to the left of the host car's lane (count)
  lanes        lanes of the road (count)
  lane_width   [m]
  speed        host car's speed [m/s]
  in_lane      1 when the in-lane system is active, else 0
  on_marking   1 when the on-marking system is active, else 0
  x, y         host car's position in the world frame [m]
  yaw          host car's heading in the world frame [rad], counter-clockwise
  s, d         host car's track coordinates [m]: arc length, lateral offset positive left
  t            simulated time [s]
  collision    1 when the host car touches another car, else 0
  off_road     1 when the host car's centre is beyond a road edge, else 0
"""
from __future__ import annotations

import sys
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from shm_bridge.vocabulary import INDICATORS

# --- constants of protocol version 1 -------------------------------------------------------------------------------
MAGIC = b"DSBRIDGE"            # 8 bytes at offset 0, written last by the world when the segment is ready
VERSION = 1
BYTE_ORDER_MARK = 0x01020304   # written as a native uint32; a reader with the other byte order sees 0x04030201
CONTROL_SIZE = 512             # bytes before slot 0 (header_size in the header)
SLOT_COUNT = 2                 # frame slots (double buffer, each guarded by its own seqlock)
SLOT_HEADER_SIZE = 256         # bytes of a slot before its frame
SLOT_ALIGN = 64                # slot sizes are rounded up to a cache line
CHANNELS = 3

MODE_LOCKSTEP = 0
MODE_FREE_RUNNING = 1

WORLD_INIT, WORLD_RUNNING, WORLD_CLOSED = 0, 1, 2            # world_state
DRIVER_NONE, DRIVER_ATTACHED, DRIVER_DETACHED = 0, 1, 2      # driver_state
DRIVER_MODE_NETWORK, DRIVER_MODE_MANUAL = 0, 1               # driver_mode: who drives
DRIVER_MODES = ("network", "manual")

N_INDICATORS = len(INDICATORS)
N_ACTION = 3                   # steer, accel, brake (shm_bridge.vocabulary.Action)

# --- the truth record ----------------------------------------------------------------------------------------------
TRUTH_EXTRAS: tuple[str, ...] = ("lanes_left", "lanes", "lane_width", "speed", "in_lane", "on_marking",
                                 "x", "y", "yaw", "s", "d", "t", "collision", "off_road")
TRUTH_FIELDS: tuple[str, ...] = INDICATORS + TRUTH_EXTRAS
TRUTH_LEN = len(TRUTH_FIELDS)
TRUTH_INDEX: dict[str, int] = {name: i for i, name in enumerate(TRUTH_FIELDS)}
EGO_FIELDS: tuple[str, ...] = ("x", "y", "yaw", "s", "d")   # the order of sim's ego pose rows
TRUTH_UNITS: dict[str, str] = {
    **{n: ("rad" if n == "angle" else "0/1" if n == "fast" else "m") for n in INDICATORS},
    "lanes_left": "count", "lanes": "count", "lane_width": "m", "speed": "m/s", "in_lane": "0/1",
    "on_marking": "0/1", "x": "m", "y": "m", "yaw": "rad", "s": "m", "d": "m", "t": "s", "collision": "0/1",
    "off_road": "0/1",
}
TRUTH_MEANING: dict[str, str] = {
    **{n: "indicator, as docs/affordances.md defines it" for n in INDICATORS},
    "lanes_left": "lanes to the left of the host car's lane", "lanes": "lanes of the road",
    "lane_width": "lane width", "speed": "host car's speed", "in_lane": "1: the in-lane system is active",
    "on_marking": "1: the on-marking system is active", "x": "host car's position, world frame",
    "y": "host car's position, world frame", "yaw": "host car's heading, counter-clockwise",
    "s": "arc length along the track", "d": "lateral offset from the track's reference line, positive left",
    "t": "simulated time", "collision": "1: the host car touches another car",
    "off_road": "1: the host car's centre is beyond a road edge",
}
_FLAGS = ("in_lane", "on_marking", "collision", "off_road")
_COUNTS = ("lanes_left", "lanes")


def pack_truth(values: Mapping[str, float] | None = None, /, *, partial: bool = False, **fields) -> np.ndarray:
    """The truth record (float64[TRUTH_LEN]) from a {field: value} mapping and/or keyword fields.

    Booleans become 0/1. An `ego` entry ([x, y, yaw, s, d], as sim's GroundTruth.ego) and an `indicators` entry
    (the 14 in canonical order) are expanded. Every field must be given unless partial=True, which fills NaN.
    """
    merged: dict = dict(values or {})
    merged.update(fields)
    out = np.full(TRUTH_LEN, np.nan, dtype=np.float64)
    given: set[str] = set()
    if "indicators" in merged:
        ind = np.asarray(merged.pop("indicators"), dtype=np.float64)
        if ind.shape != (N_INDICATORS,):
            raise ValueError(f"expected {N_INDICATORS} indicators, got shape {ind.shape}")
        out[:N_INDICATORS] = ind
        given.update(INDICATORS)
    if "ego" in merged:
        ego = np.asarray(merged.pop("ego"), dtype=np.float64).reshape(-1)
        if ego.shape != (len(EGO_FIELDS),):
            raise ValueError(f"expected ego = [x, y, yaw, s, d], got shape {ego.shape}")
        for name, v in zip(EGO_FIELDS, ego):
            out[TRUTH_INDEX[name]] = v
        given.update(EGO_FIELDS)
    for name, v in merged.items():
        if name not in TRUTH_INDEX:
            if name in ("cars", "lost"):   # known keys of sim's records that the bridge does not carry
                continue
            raise KeyError(f"unknown truth field {name!r}; fields are {', '.join(TRUTH_FIELDS)}")
        out[TRUTH_INDEX[name]] = float(v)
        given.add(name)
    if not partial:
        missing = [n for n in TRUTH_FIELDS if n not in given]
        if missing:
            raise KeyError(f"truth record lacks {', '.join(missing)}")
    return out


def pack_truth_arrays(indicators, ego, *, lanes_left: int, lanes: int, lane_width: float, speed: float,
                      in_lane: bool, on_marking: bool, t: float, collision: bool = False,
                      off_road: bool = False) -> np.ndarray:
    """The truth record from arrays: indicators (14, canonical order) and ego ([x, y, yaw, s, d])."""
    return pack_truth(indicators=indicators, ego=ego, lanes_left=lanes_left, lanes=lanes, lane_width=lane_width,
                      speed=speed, in_lane=in_lane, on_marking=on_marking, t=t, collision=collision,
                      off_road=off_road)


def check_truth(truth) -> np.ndarray:
    """`truth` as a float64[TRUTH_LEN] array (a mapping is packed), or ValueError."""
    if isinstance(truth, Mapping):
        return pack_truth(truth)
    arr = np.asarray(truth, dtype=np.float64)
    if arr.shape != (TRUTH_LEN,):
        raise ValueError(f"truth record must have shape ({TRUTH_LEN},) (fields {', '.join(TRUTH_FIELDS)}), "
                         f"got {arr.shape}")
    return arr


def unpack_truth(truth) -> dict[str, float | int | bool]:
    """{field: value} in record order; counts as int, flags as bool, everything else float."""
    arr = check_truth(truth)
    out: dict[str, float | int | bool] = {}
    for name, v in zip(TRUTH_FIELDS, arr):
        v = float(v)
        if name in _FLAGS:
            out[name] = bool(v != 0.0) if v == v else False
        elif name in _COUNTS and v == v:
            out[name] = int(round(v))
        else:
            out[name] = v
    return out


def truth_indicators(truth) -> np.ndarray:
    """The 14 indicators (canonical order) of a truth record, as a copy."""
    return np.array(check_truth(truth)[:N_INDICATORS], dtype=np.float64)


def truth_ego(truth) -> np.ndarray:
    """[x, y, yaw, s, d] of a truth record."""
    arr = check_truth(truth)
    return np.array([arr[TRUTH_INDEX[n]] for n in EGO_FIELDS], dtype=np.float64)


# --- the byte layout -----------------------------------------------------------------------------------------------
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


_CTYPES = {"uint8_t": ("<u1", 1), "uint32_t": ("<u4", 4), "int32_t": ("<i4", 4), "uint64_t": ("<u8", 8),
           "double": ("<f8", 8)}

def _block(writer: str, *rows) -> tuple[Field, ...]:
    return tuple(Field(*row, writer=writer) for row in rows)


CONTROL_FIELDS: tuple[Field, ...] = (
    # the header: written once by the world before `magic`, never changed afterwards
    *_block("world (once)",
            ("magic", "uint8_t", 8, 0, '"DSBRIDGE", stored last, when the segment is ready'),
            ("version", "uint32_t", 1, 8, "protocol version (1)"),
            ("header_size", "uint32_t", 1, 12, "bytes before slot 0 (512)"),
            ("layout_size", "uint64_t", 1, 16, "bytes of the whole segment"),
            ("height", "uint32_t", 1, 24, "frame rows (210)"),
            ("width", "uint32_t", 1, 28, "frame columns (280)"),
            ("channels", "uint32_t", 1, 32, "frame channels (3: R, G, B)"),
            ("frame_size", "uint32_t", 1, 36, "height * width * channels"),
            ("truth_len", "uint32_t", 1, 40, "float64 values in a truth record (28)"),
            ("n_indicators", "uint32_t", 1, 44, "indicators in an estimate (14)"),
            ("slot_count", "uint32_t", 1, 48, "frame slots (2)"),
            ("slot_size", "uint32_t", 1, 52, "bytes per slot: 256 + frame_size, rounded up to 64"),
            ("mode", "uint32_t", 1, 56, "0 = lock-step, 1 = free-running"),
            ("byte_order", "uint32_t", 1, 60, "0x01020304 in the writer's byte order")),
    # the world's cache line: stored by the world only
    *_block("world",
            ("driver_bell", "uint32_t", 1, 64, "futex word the driver sleeps on"),
            ("world_state", "uint32_t", 1, 68, "0 = initialising, 1 = running, 2 = closed"),
            ("world_pid", "int32_t", 1, 72, "process id of the world"),
            ("world_heartbeat_ns", "uint64_t", 1, 80, "CLOCK_MONOTONIC [ns], refreshed every <= 200 ms"),
            ("frame_seq", "uint64_t", 1, 88, "seq of the newest complete frame (0: none yet)")),
    # the driver's cache line: stored by the driver only
    *_block("driver",
            ("world_bell", "uint32_t", 1, 128, "futex word the world sleeps on"),
            ("driver_state", "uint32_t", 1, 132, "0 = none, 1 = attached, 2 = detached"),
            ("driver_pid", "int32_t", 1, 136, "process id of the driver"),
            ("driver_heartbeat_ns", "uint64_t", 1, 144, "CLOCK_MONOTONIC [ns], refreshed every <= 200 ms"),
            ("driver_seen_seq", "uint64_t", 1, 152, "seq of the newest frame the driver has taken")),
    # shared flags: stored whole by either side, which then rings the other side's bell
    *_block("either",
            ("paused", "uint32_t", 1, 192, "1 = paused"),
            ("driver_mode", "uint32_t", 1, 196, "who drives: 0 = network, 1 = manual/expert")),
    # the action record: stored by the driver under the seqlock `action_lock`
    *_block("driver",
            ("action_lock", "uint64_t", 1, 256, "seqlock: odd while the record is being written"),
            ("action_seq", "uint64_t", 1, 264, "seq of the frame this action answers (0: none yet)"),
            ("action", "double", N_ACTION, 272, "steer [-1, 1] (+ left), accel [0, 1], brake [0, 1]"),
            ("estimate", "double", N_INDICATORS, 296, "estimated indicators, canonical order (NaN: none)")),
)

SLOT_FIELDS: tuple[Field, ...] = _block(
    "world",   # under the slot's seqlock `lock`
    ("lock", "uint64_t", 1, 0, "seqlock: odd while the slot is being written"),
    ("seq", "uint64_t", 1, 8, "seq of the frame in this slot"),
    ("truth", "double", TRUTH_LEN, 16, "truth record of the frame (TRUTH_FIELDS)"),
    # frame: uint8_t[height][width][channels] at offset SLOT_HEADER_SIZE, row-major, RGB
)

FUTEX_WORDS = ("driver_bell", "world_bell")


def _offsets(fields) -> dict[str, int]:
    return {f.name: f.offset for f in fields}


CONTROL: dict[str, Field] = {f.name: f for f in CONTROL_FIELDS}
SLOT: dict[str, Field] = {f.name: f for f in SLOT_FIELDS}
OFFSET: dict[str, int] = _offsets(CONTROL_FIELDS)
SLOT_OFFSET: dict[str, int] = _offsets(SLOT_FIELDS)


def _dtype(fields, itemsize: int) -> np.dtype:
    return np.dtype({"names": [f.name for f in fields],
                     "formats": [(f.numpy, (f.count,)) if f.count > 1 else f.numpy for f in fields],
                     "offsets": [f.offset for f in fields], "itemsize": itemsize})


CONTROL_DTYPE = _dtype(CONTROL_FIELDS, CONTROL_SIZE)
SLOT_HEADER_DTYPE = _dtype(SLOT_FIELDS, SLOT_HEADER_SIZE)


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


_validate(CONTROL_FIELDS, CONTROL_SIZE, "control")
_validate(SLOT_FIELDS, SLOT_HEADER_SIZE, "slot")
for _w in FUTEX_WORDS:
    assert CONTROL[_w].ctype == "uint32_t" and CONTROL[_w].offset % 4 == 0


def slot_size(frame_size: int) -> int:
    """Bytes of one slot: its header plus the frame, rounded up to SLOT_ALIGN."""
    return -(-(SLOT_HEADER_SIZE + frame_size) // SLOT_ALIGN) * SLOT_ALIGN


def layout_size(height: int, width: int, channels: int = CHANNELS) -> int:
    """Bytes of the whole segment for frames of height x width x channels."""
    return CONTROL_SIZE + SLOT_COUNT * slot_size(height * width * channels)


def slot_offset(index: int, height: int, width: int, channels: int = CHANNELS) -> int:
    return CONTROL_SIZE + index * slot_size(height * width * channels)


def header_values(height: int, width: int, lockstep: bool) -> dict[str, int]:
    """The header fields (all but magic) of a segment for the given frame size and mode."""
    frame_size = height * width * CHANNELS
    return {"version": VERSION, "header_size": CONTROL_SIZE, "layout_size": layout_size(height, width),
            "height": height, "width": width, "channels": CHANNELS, "frame_size": frame_size,
            "truth_len": TRUTH_LEN, "n_indicators": N_INDICATORS, "slot_count": SLOT_COUNT,
            "slot_size": slot_size(frame_size), "mode": MODE_LOCKSTEP if lockstep else MODE_FREE_RUNNING,
            "byte_order": BYTE_ORDER_MARK}


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


def c_header() -> str:
    """The C declarations of protocol version 1, as docs/shm-protocol.md shows them."""
    ctrl, ctrl_asserts = _c_members(CONTROL_FIELDS, CONTROL_SIZE, "ds_control")
    slot, slot_asserts = _c_members(SLOT_FIELDS, SLOT_HEADER_SIZE, "ds_slot")
    truth = "\n".join(f"    DS_T_{n.upper():<13} = {i:>2},  /* [{TRUTH_UNITS[n]}] */"
                      for i, n in enumerate(TRUTH_FIELDS))
    return "\n".join([
        "/* drivestudio shared-memory bridge, protocol version 1 (generated by python -m shm_bridge.layout) */",
        "#ifndef DS_BRIDGE_H",
        "#define DS_BRIDGE_H",
        "#include <stddef.h>",
        "#include <stdint.h>",
        "",
        f'#define DS_MAGIC            "{MAGIC.decode()}"   /* 8 bytes, no terminating NUL */',
        f"#define DS_VERSION          {VERSION}u",
        f"#define DS_BYTE_ORDER_MARK  0x{BYTE_ORDER_MARK:08x}u",
        f"#define DS_CONTROL_SIZE     {CONTROL_SIZE}u",
        f"#define DS_SLOT_COUNT       {SLOT_COUNT}u",
        f"#define DS_SLOT_HEADER_SIZE {SLOT_HEADER_SIZE}u   /* the frame starts here inside a slot */",
        f"#define DS_SLOT_ALIGN       {SLOT_ALIGN}u",
        f"#define DS_TRUTH_LEN        {TRUTH_LEN}u",
        f"#define DS_N_INDICATORS     {N_INDICATORS}u",
        f"enum {{ DS_MODE_LOCKSTEP = {MODE_LOCKSTEP}, DS_MODE_FREE_RUNNING = {MODE_FREE_RUNNING} }};",
        f"enum {{ DS_WORLD_INIT = {WORLD_INIT}, DS_WORLD_RUNNING = {WORLD_RUNNING}, "
        f"DS_WORLD_CLOSED = {WORLD_CLOSED} }};",
        f"enum {{ DS_DRIVER_NONE = {DRIVER_NONE}, DS_DRIVER_ATTACHED = {DRIVER_ATTACHED}, "
        f"DS_DRIVER_DETACHED = {DRIVER_DETACHED} }};",
        f"enum {{ DS_DRIVER_MODE_NETWORK = {DRIVER_MODE_NETWORK}, DS_DRIVER_MODE_MANUAL = {DRIVER_MODE_MANUAL} }};",
        "",
        "typedef struct ds_control {",
        *ctrl,
        "} ds_control;",
        "",
        "typedef struct ds_slot {       /* slot i starts at header_size + i * slot_size */",
        *slot,
        "    /* uint8_t frame[height][width][channels] follows at offset DS_SLOT_HEADER_SIZE */",
        "} ds_slot;",
        "",
        "enum ds_truth_field {          /* index into ds_slot.truth */",
        truth,
        "};",
        "",
        *ctrl_asserts,
        *slot_asserts,
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


def _markdown_truth() -> str:
    rows = ["| index | field | unit | meaning |", "|---:|---|---|---|"]
    rows += [f"| {i} | `{n}` | {TRUTH_UNITS[n]} | {TRUTH_MEANING[n]} |" for i, n in enumerate(TRUTH_FIELDS)]
    return "\n".join(rows)


def doc_blocks() -> dict[str, str]:
    """The parts of docs/shm-protocol.md that are generated from this module, by marker name."""
    return {"control-table": _markdown_fields(CONTROL_FIELDS), "slot-table": _markdown_fields(SLOT_FIELDS),
            "truth-table": _markdown_truth(), "c-header": "```c\n" + c_header() + "```"}


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
