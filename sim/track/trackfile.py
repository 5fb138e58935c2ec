"""The track file format (docs/tracks.md): reading, validating and writing.

{"name": str, "lanes": 1..4, "lane_width": m (default 4.0),
 "segments": [{"type": "straight", "length": m},
              {"type": "arc", "radius": m, "angle_deg": deg, "turn": "left" | "right"}, ...]}

s = 0 is the start of the first segment, which heads along +x from the origin. A track must close: its
end pose may be off the start by at most 0.5 m and 0.01 rad.

Bad input is refused with a TrackError of one line that names the file and the field and says what is
allowed, before anything is sampled or allocated: every bound below (docs/tracks.md, "Limits") is checked on
the segment specs themselves. Where tracks come from (presets, files, procedural:SEED) is sim/track/library.py.
"""
from __future__ import annotations

import json
import math
from functools import partial
from pathlib import Path

import numpy as np

from core import inputs
from core.inputs import InputError, fmt_number, show
from core.worlds.highway import MAX_LANES  # the highway declaration owns the lane limits
from sim.track.segments import Arc, Segment, Straight
from sim.track.track import VERGE_WIDTH, Track

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

TRACK_KEYS = ("name", "lanes", "lane_width", "segments")
SEGMENT_KEYS = {"straight": ("type", "length"), "arc": ("type", "radius", "angle_deg", "turn")}


class TrackError(InputError):
    """A track that cannot be built: bad fields, no closure, too tight, crossing itself, unknown preset."""


check_keys = partial(inputs.check_keys, error=TrackError)
number = partial(inputs.number, error=TrackError)

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
        raise TrackError(f"the segments add up to {total:.0f} m; a track may be at most "
                         f"{fmt_number(MAX_TRACK_LENGTH)} m "
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
            raise TrackError(f"{where}: segment {i}: an arc of radius {fmt_number(seg['radius'])} m is too tight for "
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
                         f"at most {fmt_number(MAX_TRACK_LENGTH)} m long in at most {MAX_SEGMENTS} segments")
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



def write_track(track: Track, path: Path) -> None:
    Path(path).write_text(json.dumps(track.spec, indent=2) + "\n")
