"""The track file format (docs/tracks.md): reading, validating and writing.

{"name": str, "lanes": 1..4, "lane_width": m (default 4.0),
 "segments": [{"type": "straight", "length": m},
              {"type": "arc", "radius": m, "angle_deg": deg, "turn": "left" | "right"}, ...]}

s = 0 is the start of the first segment, which heads along +x from the origin. A track must close: its
end pose may be off the start by at most 0.5 m and 0.01 rad.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from assets import TRACKS_DIR

from .segments import Arc, Segment, Straight
from .track import VERGE_WIDTH, Track

MAX_LANES = 4
LANE_WIDTH_RANGE = (3.0, 5.0)        # [m] the on-marking bands (h = 1.2 m) must not touch each other
CLOSURE_TOLERANCE = (0.5, 0.01)      # [m], [rad]
MIN_INNER_EDGE_RADIUS = 12.0         # [m] radius of an arc's inner road edge
CLEARANCE = VERGE_WIDTH + 1.0        # [m] beyond the edges that must stay clear of other parts of the loop


class TrackError(ValueError):
    """A track that cannot be built: bad fields, no closure, too tight, crossing itself, unknown preset."""


def _number(spec: dict, key: str, where: str, positive: bool = True) -> float:
    if key not in spec:
        raise TrackError(f"{where}: missing '{key}'")
    v = spec[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise TrackError(f"{where}: '{key}' must be a number, got {v!r}")
    if positive and v <= 0:
        raise TrackError(f"{where}: '{key}' must be positive, got {v}")
    return float(v)


def build_segments(seg_specs: list) -> list[Segment]:
    """Chain segment specs from the origin heading +x."""
    if not isinstance(seg_specs, list) or not seg_specs:
        raise TrackError("'segments' must be a non-empty list")
    x, y, h = 0.0, 0.0, 0.0
    segments: list[Segment] = []
    for i, spec in enumerate(seg_specs):
        where = f"segment {i}"
        if not isinstance(spec, dict):
            raise TrackError(f"{where}: expected an object, got {spec!r}")
        kind = spec.get("type")
        if kind == "straight":
            seg: Segment = Straight(x, y, h, _number(spec, "length", where))
        elif kind == "arc":
            radius = _number(spec, "radius", where)
            angle_deg = _number(spec, "angle_deg", where)
            if angle_deg > 360:
                raise TrackError(f"{where}: 'angle_deg' must be at most 360, got {angle_deg}")
            turn = spec.get("turn")
            if turn not in ("left", "right"):
                raise TrackError(f"{where}: 'turn' must be 'left' or 'right', got {turn!r}")
            sign = 1.0 if turn == "left" else -1.0
            seg = Arc(x, y, h, radius, sign * math.radians(angle_deg))
        else:
            raise TrackError(f"{where}: 'type' must be 'straight' or 'arc', got {kind!r}")
        segments.append(seg)
        x, y, h = seg.end_pose()
    return segments


def track_from_spec(spec: dict, lanes: int | None = None, lane_width: float | None = None) -> Track:
    """Build and validate a track from its JSON object; `lanes`/`lane_width` override the file's."""
    if not isinstance(spec, dict):
        raise TrackError(f"a track must be a JSON object, got {type(spec).__name__}")
    name = spec.get("name", "unnamed")
    if not isinstance(name, str) or not name:
        raise TrackError("'name' must be a non-empty string")
    where = f"track '{name}'"
    n = lanes if lanes is not None else spec.get("lanes", 3)
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_LANES:
        raise TrackError(f"{where}: lanes must be an integer from 1 to {MAX_LANES}, got {n!r}")
    w = lane_width if lane_width is not None else spec.get("lane_width", 4.0)
    if isinstance(w, bool) or not isinstance(w, (int, float)) or not LANE_WIDTH_RANGE[0] <= w <= LANE_WIDTH_RANGE[1]:
        raise TrackError(f"{where}: lane_width must be {LANE_WIDTH_RANGE[0]} to {LANE_WIDTH_RANGE[1]} m, got {w!r}")
    try:
        segments = build_segments(spec.get("segments"))
    except TrackError as e:
        raise TrackError(f"{where}: {e}") from None
    clean = {"name": name, "lanes": n, "lane_width": float(w), "segments": spec["segments"]}
    track = Track(name, segments, n, float(w), spec=clean)
    validate(track)
    return track


def validate(track: Track) -> None:
    where = f"track '{track.name}'"
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
    """
    r = track.half_width + CLEARANCE
    step = 2.0
    s = np.arange(0.0, track.length, step)
    x, y, _ = track.pose(s)
    for lo in range(0, len(s), 256):  # blocks keep memory flat on long tracks
        blk = slice(lo, lo + 256)
        far = np.abs(track.gap(s[blk, None], s[None, :])) >= math.pi * r
        dist = np.hypot(x[blk, None] - x[None, :], y[blk, None] - y[None, :])
        bad = far & (dist < 2 * r - step)
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise TrackError(f"track '{track.name}' runs into itself: s = {s[lo + i]:.0f} m and s = {s[j]:.0f} m "
                             f"are {dist[i, j]:.1f} m apart (the road and verges need {2 * r:.1f} m)")


def read_json(path: Path) -> dict:
    try:
        text = Path(path).read_text()
    except FileNotFoundError:
        raise TrackError(f"no such file: {path}") from None
    except OSError as e:
        raise TrackError(f"cannot read {path}: {e.strerror}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise TrackError(f"{path}: malformed JSON at line {e.lineno} column {e.colno}: {e.msg}") from None


def preset_names() -> list[str]:
    return sorted(p.stem for p in TRACKS_DIR.glob("*.json"))


def load_track(ref, lanes: int | None = None, lane_width: float | None = None) -> Track:
    """A track from a JSON object, a preset name, 'procedural:SEED', or a path to a track file."""
    if isinstance(ref, dict):
        return track_from_spec(ref, lanes, lane_width)
    if not isinstance(ref, (str, Path)):
        raise TrackError(f"a track is an object, a preset name or a file path, got {ref!r}")
    ref = str(ref)
    if ref.startswith("procedural:"):
        from .procedural import procedural_spec
        seed_text = ref.split(":", 1)[1]
        if not seed_text.isdigit():
            raise TrackError(f"'{ref}': the seed of a procedural track must be a non-negative integer")
        return track_from_spec(procedural_spec(int(seed_text)), lanes, lane_width)
    preset = TRACKS_DIR / f"{ref}.json"
    if "/" not in ref and not ref.endswith(".json"):
        if not preset.is_file():
            raise TrackError(f"unknown track preset '{ref}' (presets: {', '.join(preset_names())}; "
                             f"or give a .json file or procedural:SEED)")
        return track_from_spec(read_json(preset), lanes, lane_width)
    return track_from_spec(read_json(Path(ref)), lanes, lane_width)


def write_track(track: Track, path: Path) -> None:
    Path(path).write_text(json.dumps(track.spec, indent=2) + "\n")
