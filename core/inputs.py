"""Reading what users give: the one bounded, strict reader of JSON input files and the checks of their fields.

Every JSON input (tracks, scenarios, sidewalk paths and obstacle files, benchmark suites) is read by `read_json`:
at most MAX_JSON_BYTES bytes, regular files only (never blocking on a FIFO or a device), UTF-8, strict JSON (no
NaN/Infinity, no duplicate keys, no absurd numbers, at most MAX_JSON_DEPTH levels). Fields are checked by
`check_keys` (unknown fields refused, the nearest valid one suggested) and `number` (finite, typed, in range).
Each refusal is one line that names the file and the field; `error` is the caller's exception class, so that
each format keeps its own (TrackError, ScenarioError, SuiteError, ...), all of them InputErrors by default.
"""
from __future__ import annotations

import difflib
import json
import math
import numbers
import os
import stat
from typing import Any, Literal, overload

import numpy as np

# --- limits of every JSON input file, enforced by read_json
MAX_JSON_BYTES = 1 << 20             # 1 MiB: at most this many bytes are ever read
MAX_JSON_DEPTH = 32                  # nesting of arrays and objects (the outermost one is level 1)
MAX_JSON_INT_DIGITS = 30             # longer integer literals are refused (Python refuses > 4300 itself)


class InputError(ValueError):
    """A user's file or value that cannot be used; the message is one line naming the file and the field."""


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


def fmt_number(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e16 else f"{x:g}"


def check_keys(obj: dict, allowed, where: str, error: type[Exception] = InputError, kind: str = "") -> None:
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


@overload
def number(obj: dict, key: str, where: str, *, lo: float | None = None, hi: float | None = None,
           lo_open: bool = False, unit: str = "", default: Any = _MISSING, integer: Literal[False] = False,
           error: type[Exception] = InputError) -> float: ...


@overload
def number(obj: dict, key: str, where: str, *, lo: float | None = None, hi: float | None = None,
           lo_open: bool = False, unit: str = "", default: Any = _MISSING, integer: Literal[True],
           error: type[Exception] = InputError) -> int: ...


def number(obj: dict, key: str, where: str, *, lo: float | None = None, hi: float | None = None,
           lo_open: bool = False, unit: str = "", default: Any = _MISSING, integer: bool = False,
           error: type[Exception] = InputError) -> float:
    """obj[key] as a finite float (an int when `integer`) within [lo, hi] ((lo, hi] when `lo_open`).

    Booleans, strings, NaN and infinities are refused; the message names the field and the allowed range.
    """
    u = f" {unit}" if unit else ""
    kind = "an integer" if integer else "a number"
    if lo is not None and lo_open and lo == 0:   # "positive and at most 10000 m"
        upto = f" at most {fmt_number(hi)}{u}" if hi is not None else ""
        allowed = f"positive{' and' + upto if upto else ''}"
        expected = f"a positive {kind.split()[-1]}{' of' + upto if upto else ''}"
    else:
        if lo is not None and hi is not None:
            bounds = (f"{'more than' if lo_open else 'from'} {fmt_number(lo)} {'and at most' if lo_open else 'to'} "
                      f"{fmt_number(hi)}")
        elif lo is not None:
            bounds = f"{'more than' if lo_open else 'at least'} {fmt_number(lo)}"
        elif hi is not None:
            bounds = f"at most {fmt_number(hi)}"
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
        raise error(f"{where}: '{key}' must be {allowed}, got {fmt_number(v)}")
    return int(v) if integer else float(v)



# --- bounded JSON input -------------------------------------------------------------------------------------------
_FILE_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
               (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def _not_regular(mode: int) -> str | None:
    if stat.S_ISREG(mode):
        return None
    return next((name for test, name in _FILE_KINDS if test(mode)), "not a regular file")


def read_bytes(path, what: str = "JSON", *, error: type[Exception] = InputError,
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
    stack: list[tuple[dict | list, int, tuple]] = [(obj, 1, ())] if isinstance(obj, (dict, list)) and obj else []
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


def parse_json_text(text: str, source: str = "<text>", what: str = "JSON", *,
                    error: type[Exception] = InputError, max_depth: int = MAX_JSON_DEPTH):
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


def read_json(path, what: str = "JSON", *, error: type[Exception] = InputError, max_bytes: int = MAX_JSON_BYTES,
              max_depth: int = MAX_JSON_DEPTH):
    """The parsed contents of a JSON input file, within this module's limits (MAX_JSON_BYTES, MAX_JSON_DEPTH).

    Refuses, with one line naming the file, what is missing, not a regular file, larger than max_bytes, not
    UTF-8 (a leading byte-order mark is allowed), malformed, nested too deep or holding NaN/Infinity. `what`
    names the kind of file in messages; `error` is the exception class raised (InputError by default).
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

