"""The studio's WebSocket messages (docs/studio.md lists them): what a page may send, checked field by field, and
the frame message the server sends.

A page sends JSON text messages of at most MAX_MESSAGE bytes, {"type": ..., fields}. `parse` turns one into a
`Message` or raises ProtocolError with one line the page shows; a message that is refused changes nothing.

The server sends JSON text messages (hello, role, error, info) and one binary frame message per published step:

    4 bytes   big-endian length H of the header
    H bytes   UTF-8 JSON: the step's state, with "images": [{"name", "bytes", "width", "height"}, ...]
    ...       the images' JPEG bytes, one after the other, in the header's order
"""
from __future__ import annotations

import json
import re
import struct
from dataclasses import dataclass, field

from core.inputs import check_keys, number, show

MAX_MESSAGE = 4096                      # [bytes] a page's message; more is refused
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")   # recording names, checkpoint names (never a path)
TRACK = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}|procedural:\d{1,9}")   # presets and procedural tracks or paths
MAX_SEED = 2**32 - 1

# type -> (allowed fields, who may send it: "wheel" = the page that drives, "view" = also a --view ...,control page)
TYPES: dict[str, tuple[tuple[str, ...], str]] = {
    "ack": (("type", "seq"), "any"),
    "claim": (("type",), "any"),
    "pause": (("type",), "view"),
    "resume": (("type",), "view"),
    "step": (("type",), "view"),
    "pace": (("type", "realtime"), "wheel"),
    "driver": (("type", "name"), "wheel"),
    "mode": (("type", "mode"), "wheel"),
    "operation": (("type", "operation"), "wheel"),
    "reset": (("type", "seed", "track", "path"), "wheel"),
    "record": (("type", "on", "name"), "wheel"),
    "input": (("type", "keys", "gamepad", "t"), "wheel"),
}
KEYS = ("left", "right", "up", "down")
PAD = ("steer", "throttle", "brake")


class ProtocolError(ValueError):
    """A page's message that cannot be used: one line for the page."""


@dataclass(frozen=True)
class Message:
    type: str
    fields: dict = field(default_factory=dict)

    @property
    def who(self) -> str:
        return TYPES[self.type][1]


def _flag(obj: dict, key: str, where: str) -> bool:
    v = obj.get(key)
    if not isinstance(v, bool):
        raise ProtocolError(f"{where}: '{key}' must be true or false, got {show(v)}")
    return v


def _text(obj: dict, key: str, where: str, pattern: re.Pattern, what: str) -> str:
    v = obj.get(key)
    if not isinstance(v, str) or not pattern.fullmatch(v):
        raise ProtocolError(f"{where}: '{key}' must be {what}, got {show(v)}")
    return v


def _input(obj: dict) -> dict:
    keys = obj.get("keys", {})
    if not isinstance(keys, dict):
        raise ProtocolError(f"input: 'keys' must be an object of {', '.join(KEYS)}, got {show(keys)}")
    check_keys(keys, KEYS, "input.keys", ProtocolError)
    out: dict = {"keys": {k: _flag(keys, k, "input.keys") for k in keys}}
    pad = obj.get("gamepad")
    if pad is not None:
        if not isinstance(pad, dict):
            raise ProtocolError(f"input: 'gamepad' must be an object of {', '.join(PAD)} or null, got {show(pad)}")
        check_keys(pad, PAD, "input.gamepad", ProtocolError)
        out["gamepad"] = {k: number(pad, k, "input.gamepad", lo=-1.0 if k == "steer" else 0.0, hi=1.0, default=0.0,
                                    error=ProtocolError) for k in PAD}
    if "t" in obj:
        out["t"] = number(obj, "t", "input", lo=0.0, hi=1e12, error=ProtocolError)
    return out


def _fields(kind: str, obj: dict) -> dict:
    if kind == "ack":
        return {"seq": number(obj, "seq", "ack", lo=0, hi=2**53, integer=True, error=ProtocolError)}
    if kind == "pace":
        return {"realtime": _flag(obj, "realtime", "pace")}
    if kind == "driver":
        return {"name": _text(obj, "name", "driver", NAME, "the name of a driver the page offers")}
    if kind in ("mode", "operation"):
        return {kind: _text(obj, kind, kind, NAME, f"the name of a {kind}")}
    if kind == "reset":
        out: dict = {}
        if "seed" in obj:
            out["seed"] = number(obj, "seed", "reset", lo=0, hi=MAX_SEED, integer=True, error=ProtocolError)
        for key in ("track", "path"):
            if key in obj:
                out[key] = _text(obj, key, "reset", TRACK, f"a preset {key} name or procedural:SEED")
        return out
    if kind == "record":
        rec: dict = {"on": _flag(obj, "on", "record")}
        if obj.get("name") is not None:
            rec["name"] = _text(obj, "name", "record", NAME, "a name of letters, digits, '_', '-' and '.' "
                                "(a folder in the run's output folder)")
        return rec
    if kind == "input":
        return _input(obj)
    return {}


def parse(text: str | bytes) -> Message:
    """One message from a page, or ProtocolError."""
    if isinstance(text, bytes):
        raise ProtocolError("the studio takes JSON text messages, not binary ones")
    if len(text) > MAX_MESSAGE:
        raise ProtocolError(f"message too long ({len(text)} characters; at most {MAX_MESSAGE})")
    try:
        obj = json.loads(text, parse_constant=_no_constant)
    except (ValueError, RecursionError):
        raise ProtocolError(f"not JSON: {show(text)}") from None
    if not isinstance(obj, dict):
        raise ProtocolError(f"a message is a JSON object with a 'type', got {show(obj)}")
    kind = obj.get("type")
    if kind not in TYPES:
        raise ProtocolError(f"unknown message type {show(kind)} (types: {', '.join(TYPES)})")
    check_keys(obj, TYPES[kind][0], kind, ProtocolError)
    return Message(kind, _fields(kind, obj))


def _no_constant(name: str):
    raise ValueError(name)   # NaN and Infinity are not JSON


# --- what the server sends -----------------------------------------------------------------------------------
def pack_frame(state: dict, images: list[tuple[str, bytes, int, int]]) -> bytes:
    """The binary frame message: the state (with the images described) and the JPEG bytes."""
    head = dict(state)
    head["images"] = [{"name": n, "bytes": len(b), "width": w, "height": h} for n, b, w, h in images]
    header = json.dumps(head, separators=(",", ":"), allow_nan=False).encode()
    return b"".join([struct.pack(">I", len(header)), header] + [b for _, b, _, _ in images])


def unpack_frame(data: bytes) -> tuple[dict, dict[str, bytes]]:
    """(state, {image name: JPEG bytes}) of a frame message (for tests and tools)."""
    (n,) = struct.unpack(">I", data[:4])
    state = json.loads(data[4:4 + n])
    out, at = {}, 4 + n
    for img in state["images"]:
        out[img["name"]] = data[at:at + img["bytes"]]
        at += img["bytes"]
    return state, out


def text(kind: str, **fields) -> str:
    """A JSON text message of the server."""
    return json.dumps({"type": kind, **fields}, separators=(",", ":"), allow_nan=False)
