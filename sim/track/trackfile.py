"""The track file format (docs/tracks.md): reading, validating and writing.

{"name": str, "lanes": 1..4, "lane_width": m (default 4.0),
 "segments": [{"type": "straight", "length": m},
              {"type": "arc", "radius": m, "angle_deg": deg, "turn": "left" | "right"}, ...]}

s = 0 is the start of the first segment, which heads along +x from the origin. A track must close: its
end pose may be off the start by at most 0.5 m and 0.01 rad.

Bad input is refused with a TrackError of one line that names the file and the field and says what is
allowed, before anything is sampled or allocated: every bound below (docs/tracks.md, "Limits") is checked on
the segment specs themselves. `read_json` is the one bounded reader of JSON input files (tracks, scenarios).
"""
from __future__ import annotations

import difflib
import json
import math
import numbers
import os
import stat
from pathlib import Path

import numpy as np

from assets import TRACKS_DIR
from shm_bridge.worlds.highway import MAX_LANES  # the highway declaration owns the lane limits

from .segments import Arc, Segment, Straight
from .track import VERGE_WIDTH, Track

LANE_WIDTH_RANGE = (3.0, 5.0)        # [m] the on-marking bands (h = 1.2 m) must not touch each other
CLOSURE_TOLERANCE = (0.5, 0.01)      # [m], [rad]
MIN_INNER_EDGE_RADIUS = 12.0         # [m] radius of an arc's inner road edge
CLEARANCE = VERGE_WIDTH + 1.0        # [m] beyond the edges that must stay clear of other parts of the loop

# --- limits of a track (docs/tracks.md, "Limits"); the presets and procedural tracks (1 to 6 km, at most 17
# segments, radii 45 to 220 m, straights up to 1.5 km) sit far inside them
MAX_TRACK_LENGTH = 20_000.0          # [m] total centreline length: keeps sampling, scenery and SUMO small
MAX_SEGMENTS = 500
MAX_STRAIGHT_LENGTH = 10_000.0       # [m] one straight
MAX_ARC_RADIUS = 10_000.0            # [m] one arc (the least radius follows from the road width)
MAX_ANGLE_DEG = 360.0                # [deg] one arc sweeps (0, 360]
MAX_NAME_LENGTH = 64                 # characters of a track's name (printable, one line)
MAX_PROCEDURAL_SEED = 2**63 - 1      # procedural:SEED takes 0 .. 2**63 - 1

# --- limits of every JSON input file (tracks, scenarios), enforced by read_json
MAX_JSON_BYTES = 1 << 20             # 1 MiB: at most this many bytes are ever read
MAX_JSON_DEPTH = 32                  # nesting of arrays and objects (the outermost one is level 1)
MAX_JSON_INT_DIGITS = 30             # longer integer literals are refused (Python refuses > 4300 itself)

TRACK_KEYS = ("name", "lanes", "lane_width", "segments")
SEGMENT_KEYS = {"straight": ("type", "length"), "arc": ("type", "radius", "angle_deg", "turn")}


class TrackError(ValueError):
    """A track that cannot be built: bad fields, no closure, too tight, crossing itself, unknown preset."""


# --- one-line messages ----------------------------------------------------------------------------------------
def show(value, limit: int = 40) -> str:
    """`value` as one short line for a message: repr (escapes newlines and control characters), truncated."""
    text = repr(value)
    if not text.isprintable():
        text = ascii(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def show_path(path) -> str:
    """A file name for a message: as given when printable, escaped otherwise; never longer than 300."""
    try:
        text = os.fsdecode(path)
    except TypeError:
        text = repr(path)
    if not text.isprintable():
        text = ascii(text)
    return text if len(text) <= 300 else text[:140] + "..." + text[-140:]


def _fmt(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e16 else f"{x:g}"


def check_keys(obj: dict, allowed, where: str, error: type[Exception] = TrackError, kind: str = "") -> None:
    """Refuse any key of `obj` not in `allowed`, naming it and the nearest allowed key."""
    for key in obj:
        if key in allowed:
            continue
        hint = ""
        if isinstance(key, str):
            close = difflib.get_close_matches(key, list(allowed), n=1, cutoff=0.6)
            if close:
                hint = f" (did you mean '{close[0]}'?)"
        of = f" of {kind}" if kind else ""
        raise error(f"{where}: unknown field {show(key)}{hint}; the fields{of} are {', '.join(allowed)}")


_MISSING = object()


def number(obj: dict, key: str, where: str, *, lo: float | None = None, hi: float | None = None,
           lo_open: bool = False, unit: str = "", default=_MISSING, integer: bool = False,
           error: type[Exception] = TrackError) -> float:
    """obj[key] as a finite float (an int when `integer`) within [lo, hi] ((lo, hi] when `lo_open`).

    Booleans, strings, NaN and infinities are refused; the message names the field and the allowed range.
    """
    u = f" {unit}" if unit else ""
    kind = "an integer" if integer else "a number"
    if lo is not None and lo_open and lo == 0:   # "positive and at most 10000 m"
        upto = f" at most {_fmt(hi)}{u}" if hi is not None else ""
        allowed = f"positive{' and' + upto if upto else ''}"
        expected = f"a positive {kind.split()[-1]}{' of' + upto if upto else ''}"
    else:
        if lo is not None and hi is not None:
            bounds = f"{'more than' if lo_open else 'from'} {_fmt(lo)} {'and at most' if lo_open else 'to'} {_fmt(hi)}"
        elif lo is not None:
            bounds = f"{'more than' if lo_open else 'at least'} {_fmt(lo)}"
        elif hi is not None:
            bounds = f"at most {_fmt(hi)}"
        else:
            bounds = "in" if unit else ""
        allowed = expected = " ".join(w for w in (kind, bounds, unit) if w)
    if key not in obj:
        if default is _MISSING:
            raise error(f"{where}: missing '{key}' ({expected})")
        return default
    v = obj[key]
    if integer:
        ok = isinstance(v, numbers.Integral) and not isinstance(v, bool)
    else:
        ok = isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_)) and math.isfinite(v)
    if not ok:
        raise error(f"{where}: '{key}' must be {expected}, got {show(v)}")
    if (lo is not None and (v <= lo if lo_open else v < lo)) or (hi is not None and v > hi):
        raise error(f"{where}: '{key}' must be {allowed}, got {_fmt(v)}")
    return int(v) if integer else float(v)


def _number(spec: dict, key: str, where: str, positive: bool = True, hi: float | None = None, unit: str = "m") -> float:
    return number(spec, key, where, lo=0.0 if positive else None, lo_open=positive, hi=hi, unit=unit)


# --- segments ---------------------------------------------------------------------------------------------------
def check_segment_specs(seg_specs) -> float:
    """Validate segment specs without building anything; returns the total length [m].

    Checks the count, each segment's fields (no unknown ones), types and ranges, and the total length.
    """
    if not isinstance(seg_specs, list) or not seg_specs:
        raise TrackError(f"'segments' must be a non-empty list (at most {MAX_SEGMENTS} segments), "
                         f"got {show(seg_specs)}")
    if len(seg_specs) > MAX_SEGMENTS:
        raise TrackError(f"'segments' has {len(seg_specs)} segments; a track may have at most {MAX_SEGMENTS}")
    total = 0.0
    for i, spec in enumerate(seg_specs):
        where = f"segment {i}"
        if not isinstance(spec, dict):
            raise TrackError(f"{where}: expected an object with 'type' and its fields, got {show(spec)}")
        kind = spec.get("type")
        if not isinstance(kind, str) or kind not in SEGMENT_KEYS:  # (a list is unhashable: no dict lookup)
            check_keys(spec, tuple(dict.fromkeys(k for keys in SEGMENT_KEYS.values() for k in keys)), where)
            raise TrackError(f"{where}: 'type' must be 'straight' or 'arc', got {show(kind)}")
        check_keys(spec, SEGMENT_KEYS[kind], where, kind=f"a {kind}")
        if kind == "straight":
            total += _number(spec, "length", where, hi=MAX_STRAIGHT_LENGTH)
        else:
            radius = _number(spec, "radius", where, hi=MAX_ARC_RADIUS)
            angle_deg = _number(spec, "angle_deg", where, hi=MAX_ANGLE_DEG, unit="degrees")
            turn = spec.get("turn")
            if turn not in ("left", "right"):
                raise TrackError(f"{where}: 'turn' must be 'left' or 'right', got {show(turn)}")
            total += radius * math.radians(angle_deg)
    if total > MAX_TRACK_LENGTH:
        raise TrackError(f"the segments add up to {total:.0f} m; a track may be at most {_fmt(MAX_TRACK_LENGTH)} m "
                         f"long")
    return total


def build_segments(seg_specs: list) -> list[Segment]:
    """Chain segment specs from the origin heading +x (after check_segment_specs: O(segments), no sampling)."""
    check_segment_specs(seg_specs)
    return chain_segments(seg_specs)


def chain_segments(seg_specs: list) -> list[Segment]:
    """Chain segment specs already checked (by the caller's own rules: a track's or a sidewalk path's) from the
    origin heading +x."""
    x, y, h = 0.0, 0.0, 0.0
    segments: list[Segment] = []
    for spec in seg_specs:
        if spec["type"] == "straight":
            seg: Segment = Straight(x, y, h, float(spec["length"]))
        else:
            sign = 1.0 if spec["turn"] == "left" else -1.0
            seg = Arc(x, y, h, float(spec["radius"]), sign * math.radians(float(spec["angle_deg"])))
        segments.append(seg)
        x, y, h = seg.end_pose()
    return segments


def track_from_spec(spec: dict, lanes: int | None = None, lane_width: float | None = None) -> Track:
    """Build and validate a track from its JSON object; `lanes`/`lane_width` override the file's."""
    if not isinstance(spec, dict):
        raise TrackError(f"a track must be a JSON object with {', '.join(TRACK_KEYS)}, got {show(spec)}")
    check_keys(spec, TRACK_KEYS, "track")
    name = spec.get("name", "unnamed")
    if not isinstance(name, str) or not name or len(name) > MAX_NAME_LENGTH or not name.isprintable():
        raise TrackError(f"track: 'name' must be a non-empty line of at most {MAX_NAME_LENGTH} printable "
                         f"characters, got {show(name)}")
    where = f"track '{name}'"
    n = lanes if lanes is not None else spec.get("lanes", 3)
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_LANES:
        raise TrackError(f"{where}: lanes must be an integer from 1 to {MAX_LANES}, got {show(n)}")
    w = lane_width if lane_width is not None else spec.get("lane_width", 4.0)
    if (isinstance(w, bool) or not isinstance(w, (int, float)) or not math.isfinite(w)
            or not LANE_WIDTH_RANGE[0] <= w <= LANE_WIDTH_RANGE[1]):
        raise TrackError(f"{where}: lane_width must be {LANE_WIDTH_RANGE[0]} to {LANE_WIDTH_RANGE[1]} m, "
                         f"got {show(w)}")
    try:
        check_segment_specs(spec.get("segments"))
    except TrackError as e:
        raise TrackError(f"{where}: {e}") from None
    need = n * float(w) / 2 + MIN_INNER_EDGE_RADIUS
    for i, seg in enumerate(spec["segments"]):  # before anything is built: the cheapest refusal of all
        if seg["type"] == "arc" and seg["radius"] < need:
            raise TrackError(f"{where}: segment {i}: an arc of radius {_fmt(seg['radius'])} m is too tight for "
                             f"{n} lane(s) of {w} m (need at least {need:.1f} m)")
    segments = build_segments(spec["segments"])
    clean = {"name": name, "lanes": n, "lane_width": float(w), "segments": spec["segments"]}
    track = Track(name, segments, n, float(w), spec=clean)
    validate(track)
    return track


def validate(track: Track) -> None:
    where = f"track '{track.name}'"
    if not 0 < track.length <= MAX_TRACK_LENGTH or len(track.segments) > MAX_SEGMENTS:
        raise TrackError(f"{where} is {track.length:.0f} m long in {len(track.segments)} segments; a track may be "
                         f"at most {_fmt(MAX_TRACK_LENGTH)} m long in at most {MAX_SEGMENTS} segments")
    dist, dh = track.closure_error()
    if dist > CLOSURE_TOLERANCE[0] or dh > CLOSURE_TOLERANCE[1]:
        raise TrackError(f"{where} does not close: its end is {dist:.2f} m and {dh:.3f} rad off the start "
                         f"(at most {CLOSURE_TOLERANCE[0]} m and {CLOSURE_TOLERANCE[1]} rad allowed)")
    need = track.half_width + MIN_INNER_EDGE_RADIUS
    if track.min_radius() < need:
        raise TrackError(f"{where}: an arc of radius {track.min_radius():.1f} m is too tight for "
                         f"{track.lanes} lane(s) of {track.lane_width} m (need at least {need:.1f} m)")
    _check_no_overlap(track)


def _check_no_overlap(track: Track) -> None:
    """Reject loops whose road (plus verges) runs into another part of itself.

    With reach r = half width + clearance, distinct parts of the loop must stay 2r apart. Points less than
    pi*r apart along the loop are close by construction (curvature <= 1/r), so only farther pairs count.
    The centreline is sampled every 2 m and the samples binned into a grid of 2r cells, so that only samples
    in neighbouring cells are compared: O(samples) on any loop that does not run into itself. The pair
    reported is the first by sample index, as a scan of all pairs would find.
    """
    r = track.half_width + CLEARANCE
    step = 2.0
    s = np.arange(0.0, track.length, step)
    x, y, _ = track.pose(s)
    n = len(s)
    cell = 2 * r  # > the reach of a collision (2r - step): colliding samples lie in the same or adjacent cells
    cx = np.floor((x - x.min()) / cell).astype(np.int64) + 1  # + 1: neighbours' columns stay >= 0
    cy = np.floor((y - y.min()) / cell).astype(np.int64) + 1
    rows = int(cy.max()) + 2
    key = cx * rows + cy
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    for lo in range(0, n, 256):  # blocks keep memory flat (at most 256 * n pairs) even on a knotted loop
        blk = np.arange(lo, min(lo + 256, n))
        pi_, pj = [], []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                k = (cx[blk] + dx) * rows + (cy[blk] + dy)
                first = np.searchsorted(sorted_key, k, "left")
                count = np.searchsorted(sorted_key, k, "right") - first
                total = int(count.sum())
                if total == 0:
                    continue
                start = np.repeat(np.cumsum(count) - count, count)
                pi_.append(np.repeat(blk, count))
                pj.append(order[np.arange(total) - start + np.repeat(first, count)])
        if not pi_:
            continue
        i, j = np.concatenate(pi_), np.concatenate(pj)
        dist = np.hypot(x[i] - x[j], y[i] - y[j])
        far = np.abs(track.gap(s[i], s[j])) >= math.pi * r
        bad = np.flatnonzero(far & (dist < 2 * r - step))
        if len(bad):
            b = bad[np.lexsort((j[bad], i[bad]))[0]]
            raise TrackError(f"track '{track.name}' runs into itself: s = {s[i[b]]:.0f} m and s = {s[j[b]]:.0f} m "
                             f"are {dist[b]:.1f} m apart (the road and verges need {2 * r:.1f} m)")


# --- bounded JSON input -------------------------------------------------------------------------------------------
_FILE_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
               (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def _not_regular(mode: int) -> str | None:
    if stat.S_ISREG(mode):
        return None
    return next((name for test, name in _FILE_KINDS if test(mode)), "not a regular file")


def read_bytes(path, what: str = "track", *, error: type[Exception] = TrackError,
               max_bytes: int = MAX_JSON_BYTES) -> bytes:
    """The bytes of a regular file of at most `max_bytes`; never blocks, never reads more than max_bytes + 1.

    Directories, FIFOs, devices (/dev/zero) and sockets are refused by their type before they are opened, and
    again after (O_NONBLOCK: opening a FIFO that appeared meanwhile cannot wait for a writer).
    """
    p = show_path(path)

    def refuse_odd(mode: int) -> None:
        kind = _not_regular(mode)
        if kind:
            raise error(f"{p}: is {kind}, not a {what} file (a regular file of JSON text)")

    def opened(call):
        try:
            return call()
        except FileNotFoundError:
            raise error(f"no such file: {p}") from None
        except OSError as e:
            raise error(f"cannot read {p}: {e.strerror or e}") from None
        except (ValueError, TypeError):  # an embedded NUL character, or not a path at all
            raise error(f"not a valid file name: {p}") from None

    refuse_odd(opened(lambda: os.stat(path)).st_mode)
    fd = opened(lambda: os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)))
    try:
        st = os.fstat(fd)
        refuse_odd(st.st_mode)
        too_big = f"{p}: a {what} file may be at most {max_bytes} bytes"
        if st.st_size > max_bytes:
            raise error(f"{too_big}, this one is {st.st_size}")
        chunks, left = [], max_bytes + 1
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 16))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
        data = b"".join(chunks)
        if len(data) > max_bytes:
            raise error(f"{too_big}, this one is longer")
        return data
    except OSError as e:
        raise error(f"cannot read {p}: {e.strerror or e}") from None
    finally:
        os.close(fd)


class _Refused(Exception):
    """Raised inside the JSON parser's hooks; becomes the caller's error with the file name."""


class _OutOfRange:
    """A number JSON allows in no input of ours (NaN, Infinity, 1e999, a 31-digit integer): reported, with the
    path to it, by the walk after parsing."""

    def __init__(self, text: str):
        self.text = text

    def why(self) -> str:
        t = self.text if len(self.text) <= 24 else f"{self.text[:12]}...({len(self.text)} characters)"
        if self.text.lstrip("-") in ("NaN", "Infinity"):
            return f"{t} is not allowed: numbers must be finite"
        if self.text.lstrip("-").isdigit():
            return f"the integer {t} is out of range: integers may have at most {MAX_JSON_INT_DIGITS} digits"
        return f"the number {t} is out of range: numbers must be finite (at most about 1.8e308)"


def _parse_constant(text: str):
    return _OutOfRange(text)


def _parse_float(text: str):
    v = float(text)
    return v if math.isfinite(v) else _OutOfRange(text)


def _parse_int(text: str):
    return int(text) if len(text.lstrip("-")) <= MAX_JSON_INT_DIGITS else _OutOfRange(text)


def _pairs(pairs: list) -> dict:
    out = {}
    for key, value in pairs:
        if key in out:
            raise _Refused(f"the field {show(key)} appears twice in one object")
        out[key] = value
    return out


def _where(path: tuple) -> str:
    out = ""
    for part in path:
        if isinstance(part, str) and part.isidentifier() and part.isascii():
            out += f".{part}" if out else part
        else:
            out += f"[{part if isinstance(part, int) else show(part, 24)}]"
    out = out or "the top level"
    return out if len(out) <= 60 else out[:57] + "..."


def _walk(obj, max_depth: int) -> None:
    """Check nesting depth and refuse out-of-range numbers, iteratively (no recursion on deep input)."""
    if isinstance(obj, _OutOfRange):
        raise _Refused(f"the top level: {obj.why()}")
    stack = [(obj, 1, ())] if isinstance(obj, (dict, list)) and obj else []
    if stack and max_depth < 1:
        raise _Refused(f"the top level: JSON nested more than {max_depth} levels deep")
    while stack:
        node, depth, path = stack.pop()
        for key, value in (node.items() if isinstance(node, dict) else enumerate(node)):
            if isinstance(value, (dict, list)):
                if depth >= max_depth:
                    raise _Refused(f"{_where(path + (key,))}: JSON nested more than {max_depth} levels deep")
                if value:
                    stack.append((value, depth + 1, path + (key,)))
            elif isinstance(value, _OutOfRange):
                raise _Refused(f"{_where(path + (key,))}: {value.why()}")


def parse_json_text(text: str, source: str = "<text>", what: str = "track", *,
                    error: type[Exception] = TrackError, max_depth: int = MAX_JSON_DEPTH):
    """Parse JSON text strictly: no NaN/Infinity, no infinite numbers, no duplicate keys, at most `max_depth`
    levels of nesting. `source` (a file name) starts every message."""
    try:
        obj = json.loads(text, parse_constant=_parse_constant, parse_float=_parse_float, parse_int=_parse_int,
                         object_pairs_hook=_pairs)
        _walk(obj, max_depth)
    except json.JSONDecodeError as e:
        if not text.strip():
            raise error(f"{source}: empty; a {what} file must hold one JSON object") from None
        raise error(f"{source}: malformed JSON at line {e.lineno} column {e.colno}: {e.msg}") from None
    except RecursionError:
        raise error(f"{source}: JSON nested more than {max_depth} levels deep; a {what} file may nest "
                    f"at most {max_depth}") from None
    except _Refused as e:
        raise error(f"{source}: {e}") from None
    return obj


def read_json(path, what: str = "track", *, error: type[Exception] = TrackError, max_bytes: int = MAX_JSON_BYTES,
              max_depth: int = MAX_JSON_DEPTH):
    """The parsed contents of a JSON input file, within this module's limits (MAX_JSON_BYTES, MAX_JSON_DEPTH).

    Refuses, with one line naming the file, what is missing, not a regular file, larger than max_bytes, not
    UTF-8 (a leading byte-order mark is allowed), malformed, nested too deep or holding NaN/Infinity. `what`
    names the kind of file in messages; `error` is the exception class raised (TrackError by default).
    """
    data = read_bytes(path, what, error=error, max_bytes=max_bytes)
    p = show_path(path)
    skip = 3 if data.startswith(b"\xef\xbb\xbf") else 0  # a byte-order mark some editors write
    try:
        text = data[skip:].decode("utf-8")
    except UnicodeDecodeError as e:
        raise error(f"{p}: not UTF-8 text (byte 0x{data[skip + e.start]:02x} at offset {skip + e.start}); "
                    f"a {what} file must be UTF-8 JSON") from None
    return parse_json_text(text, p, what, error=error, max_depth=max_depth)


def preset_names() -> list[str]:
    return sorted(p.stem for p in TRACKS_DIR.glob("*.json"))


def _in_file(path, loader):
    """Run `loader` on a track that came from `path`, naming the file in what it refuses."""
    try:
        return loader()
    except TrackError as e:
        raise TrackError(f"{show_path(path)}: {e}") from None


def load_track(ref, lanes: int | None = None, lane_width: float | None = None) -> Track:
    """A track from a JSON object, a preset name, 'procedural:SEED', or a path to a track file."""
    if isinstance(ref, dict):
        return track_from_spec(ref, lanes, lane_width)
    if not isinstance(ref, (str, Path)):
        raise TrackError(f"a track is an object, a preset name or a file path, got {show(ref)}")
    ref = str(ref)
    if ref.startswith("procedural:"):
        from .procedural import procedural_spec
        seed_text = ref.split(":", 1)[1]
        if (not (seed_text.isascii() and seed_text.isdigit()) or len(seed_text) > 19
                or int(seed_text) > MAX_PROCEDURAL_SEED):
            raise TrackError(f"{show(ref)}: the seed of a procedural track must be an integer from 0 to "
                             f"{MAX_PROCEDURAL_SEED}")
        return track_from_spec(procedural_spec(int(seed_text)), lanes, lane_width)
    if "/" not in ref and not ref.endswith(".json"):
        names = preset_names()
        if ref not in names:  # looked up among the presets, never as a file name (it may be anything)
            raise TrackError(f"unknown track preset {show(ref)} (presets: {', '.join(names)}; "
                             f"or give a .json file or procedural:SEED)")
        return track_from_spec(read_json(TRACKS_DIR / f"{ref}.json"), lanes, lane_width)
    data = read_json(Path(ref), "track")
    return _in_file(ref, lambda: track_from_spec(data, lanes, lane_width))


def write_track(track: Track, path: Path) -> None:
    Path(path).write_text(json.dumps(track.spec, indent=2) + "\n")
