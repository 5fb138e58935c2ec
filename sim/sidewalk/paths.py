"""Sidewalk and park paths: closed loops 1.5-3 m wide, built with the highway's track geometry (Track, Straight,
Arc) at path scale. A path comes from a preset (assets/paths/*.json), a user's JSON file, or `procedural:SEED`.

Path file (docs/sidewalk.md, "Path files"):

    {"name": "park", "style": "park", "width": 2.0,
     "segments": [{"type": "straight", "length": 12.0},
                  {"type": "arc", "radius": 6.0, "angle_deg": 90, "turn": "left"}, ...]}

s = 0 is the start of the first segment, heading +x from the origin; d [m] is the offset from the centreline,
positive to the left. The loop must close (its end within CLOSURE_TOLERANCE of its start), every arc must be at
least `min_radius(width)` (the border zone on the inside of a bend must not fold over), and distinct parts of
the loop must stay 2 * reach apart (reach = width / 2 + BORDER_ZONE: the path, its kerbs and the hedges beside
it never run into another part of the loop). Every bound is checked on the specs before anything is built, and
bad input is refused with one PathError line that names the file and the field.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path as FilePath

import numpy as np

from assets import ASSETS_DIR
from core import inputs
from core.inputs import fmt_number, number, read_json, show
from sim.sidewalk.errors import PathError
from sim.track.procedural import close_loop
from sim.track.track import Track
from sim.track.trackfile import chain_segments

PATHS_DIR = ASSETS_DIR / "paths"
STYLES = ("sidewalk", "park", "forest")
WIDTH_RANGE = (1.5, 3.0)            # [m] path width
BORDER_ZONE = 2.0                   # [m] beyond each edge: kerb, hedges, bushes; kept clear of the loop's other parts
RADIUS_MAX = 200.0                  # [m] one arc
STRAIGHT_MAX = 200.0                # [m] one straight
LENGTH_RANGE = (30.0, 1000.0)       # [m] a user's loop (procedural loops: PROCEDURAL_LENGTH)
PROCEDURAL_LENGTH = (100.0, 500.0)  # [m]
MAX_SEGMENTS = 200
CLOSURE_TOLERANCE = (0.05, 0.01)    # [m], [rad]: a 5 cm step in a 2 m path would show
MAX_NAME = 64
MAX_SEED = 2**63 - 1
PATH_KEYS = ("name", "style", "width", "segments")
SEGMENT_KEYS = {"straight": ("type", "length"), "arc": ("type", "radius", "angle_deg", "turn")}
OVERLAP_STEP = 0.5                  # [m] centreline sampling of the self-overlap check


def min_radius(width: float) -> float:
    """The tightest arc [m] a path of `width` may take: its inner border zone must not fold over."""
    return width / 2 + BORDER_ZONE


def reach(width: float) -> float:
    """[m] from the centreline to the outer limit of the border zone."""
    return width / 2 + BORDER_ZONE


@dataclass
class SidewalkPath:
    """A validated closed path: its geometry (a one-lane Track whose lane is the path), style and width."""

    track: Track
    style: str
    ref: str                                   # how it was asked for: preset name, file or procedural:SEED
    spec: dict = field(default_factory=dict, repr=False)

    @property
    def name(self) -> str:
        return self.track.name

    @property
    def width(self) -> float:
        return self.track.lane_width

    @property
    def length(self) -> float:
        return self.track.length

    @property
    def half_width(self) -> float:
        return self.track.half_width


check_keys = partial(inputs.check_keys, error=PathError)


def _number(obj: dict, key: str, where: str, lo: float, hi: float, unit: str, lo_open: bool = False) -> float:
    """obj[key] as a finite float in [lo, hi] ((lo, hi] with lo_open): core.inputs' check, as a PathError."""
    return number(obj, key, where, lo=lo, hi=hi, unit=unit, lo_open=lo_open, error=PathError)


def check_width(width, where: str = "path") -> float:
    return _number({"width": width}, "width", where, *WIDTH_RANGE, "m")


# --- building -------------------------------------------------------------------------------------------------
def _check_segments(specs, width: float, where: str) -> None:
    if not isinstance(specs, list) or not specs:
        raise PathError(f"{where}: 'segments' must be a non-empty list of at most {MAX_SEGMENTS} segments, got "
                        f"{show(specs)}")
    if len(specs) > MAX_SEGMENTS:
        raise PathError(f"{where}: {len(specs)} segments; a path may have at most {MAX_SEGMENTS}")
    r_min = min_radius(width)
    total = 0.0
    for i, seg in enumerate(specs):
        at = f"{where}: segment {i}"
        if not isinstance(seg, dict):
            raise PathError(f"{at}: expected an object with 'type' and its fields, got {show(seg)}")
        kind = seg.get("type")
        if not isinstance(kind, str) or kind not in SEGMENT_KEYS:
            raise PathError(f"{at}: 'type' must be 'straight' or 'arc', got {show(kind)}")
        check_keys(seg, SEGMENT_KEYS[kind], at)
        if kind == "straight":
            total += _number(seg, "length", at, 0.0, STRAIGHT_MAX, "m", lo_open=True)
        else:
            asked = seg.get("radius")
            if isinstance(asked, numbers.Real) and not isinstance(asked, bool) and math.isfinite(asked) \
                    and 0 < float(asked) < r_min:
                raise PathError(f"{at}: an arc of radius {fmt_number(float(asked))} m is too tight for a path "
                                f"{fmt_number(width)} m wide (at least {r_min:g} m: width / 2 + {BORDER_ZONE:g} m)")
            radius = _number(seg, "radius", at, r_min, RADIUS_MAX, "m")
            angle = _number(seg, "angle_deg", at, 0.0, 360.0, "degrees", lo_open=True)
            if seg.get("turn") not in ("left", "right"):
                raise PathError(f"{at}: 'turn' must be 'left' or 'right', got {show(seg.get('turn'))}")
            total += radius * math.radians(angle)
    if not LENGTH_RANGE[0] <= total <= LENGTH_RANGE[1]:
        raise PathError(f"{where}: the segments add up to {total:.1f} m; a path loop is "
                        f"{fmt_number(LENGTH_RANGE[0])} to "
                        f"{fmt_number(LENGTH_RANGE[1])} m long")


def path_from_spec(spec, width: float | None = None, ref: str | None = None, style: str | None = None) -> SidewalkPath:
    """A validated path from its JSON object; `width` overrides the file's."""
    if not isinstance(spec, dict):
        raise PathError(f"a path must be a JSON object with {', '.join(PATH_KEYS)}, got {show(spec)}")
    check_keys(spec, PATH_KEYS, "path")
    name = spec.get("name", "unnamed")
    if not isinstance(name, str) or not name or len(name) > MAX_NAME or not name.isprintable():
        raise PathError(f"path: 'name' must be a non-empty line of at most {MAX_NAME} printable characters, got "
                        f"{show(name)}")
    where = f"path '{name}'"
    style = style or spec.get("style", "park")
    if not isinstance(style, str) or style not in STYLES:
        raise PathError(f"{where}: 'style' must be one of {', '.join(STYLES)}, got {show(style)}")
    w = check_width(width, where) if width is not None else _number(spec, "width", where, *WIDTH_RANGE, "m")
    _check_segments(spec.get("segments"), w, where)
    segments = chain_segments(spec["segments"])
    track = Track(name, segments, 1, w, spec={"name": name, "style": style, "width": w,
                                               "segments": spec["segments"]})
    dist, dh = track.closure_error()
    if dist > CLOSURE_TOLERANCE[0] or dh > CLOSURE_TOLERANCE[1]:
        raise PathError(f"{where} does not close: its end is {dist:.2f} m and {dh:.3f} rad off its start (at most "
                        f"{CLOSURE_TOLERANCE[0]} m and {CLOSURE_TOLERANCE[1]} rad)")
    _check_no_overlap(track, where)
    return SidewalkPath(track, style, ref or name, dict(track.spec))


def _check_no_overlap(track: Track, where: str) -> None:
    """Distinct parts of the loop stay 2 * reach apart. Points less than pi * reach apart along the loop are close
    by construction (no arc is tighter than reach), so only farther pairs count."""
    r = reach(track.lane_width)
    s = np.arange(0.0, track.length, OVERLAP_STEP)
    x, y, _ = track.pose(s)
    n = len(s)
    for lo in range(0, n, 512):   # blocks: at most 512 x n distances at a time
        i = np.arange(lo, min(lo + 512, n))
        dist = np.hypot(x[i, None] - x[None, :], y[i, None] - y[None, :])
        along = np.abs(track.gap(s[i, None], s[None, :]))
        bad = np.argwhere((along >= math.pi * r) & (dist < 2 * r - OVERLAP_STEP))
        if len(bad):
            a, b = i[bad[0, 0]], bad[0, 1]
            raise PathError(f"{where} runs into itself: s = {s[a]:.1f} m and s = {s[b]:.1f} m are "
                            f"{dist[bad[0, 0], bad[0, 1]]:.1f} m apart (the path and its borders need "
                            f"{2 * r:.1f} m)")


# --- procedural loops -----------------------------------------------------------------------------------------
def procedural_spec(seed: int, width: float | None = None) -> dict:
    """A winding closed path drawn from `seed`: a chain of arcs (radii of a few metres, some turning right)
    whose turns sum to one full turn, with straights between, closed in position by two straights
    (sim.track.procedural.close_loop). Candidates too short, too long or running into themselves are
    drawn again."""
    rng = np.random.default_rng([int(seed), 0x51DE])
    w = float(width) if width is not None else round(float(rng.uniform(*WIDTH_RANGE)), 2)
    style = STYLES[int(rng.integers(len(STYLES)))]
    r_min = min_radius(w)
    for _ in range(4000):
        n = int(rng.integers(7, 15))
        signs = np.where(rng.random(n) < 0.38, -1.0, 1.0)
        signs[0] = 1.0
        if (signs < 0).sum() < 2:   # winding: at least two bends the other way
            continue
        raw = rng.uniform(30.0, 150.0, n) * signs
        if raw.sum() < 120.0:
            continue
        angles = raw * 360.0 / raw.sum()
        if (np.abs(angles) < 12.0).any() or (np.abs(angles) > 200.0).any():
            continue
        radii = rng.uniform(r_min, r_min + 14.0, n)
        gaps = np.where(rng.random(n) < 0.35, 0.0, rng.uniform(2.0, 20.0, n))
        closed = close_loop(angles, radii, gaps)
        if closed is None:
            continue
        lengths = [sp["length"] for sp in closed if sp["type"] == "straight"]
        if min(lengths) < 2.0 or max(lengths) > STRAIGHT_MAX:
            continue
        total = sum(sp["length"] if sp["type"] == "straight" else math.radians(sp["angle_deg"]) * sp["radius"]
                    for sp in closed)
        if not PROCEDURAL_LENGTH[0] <= total <= PROCEDURAL_LENGTH[1]:
            continue
        for sp in closed:
            if sp["type"] == "straight":
                sp["length"] = round(sp["length"], 6)
        spec = {"name": f"procedural-{seed}", "style": style, "width": w, "segments": closed}
        try:
            path_from_spec(spec)
        except PathError:
            continue
        return spec
    raise PathError(f"could not draw a valid procedural path from seed {seed}")


# --- references -----------------------------------------------------------------------------------------------
def preset_names() -> list[str]:
    return sorted(p.stem for p in PATHS_DIR.glob("*.json"))


def load_path(ref, width: float | None = None) -> SidewalkPath:
    """A path from a JSON object, a preset name, 'procedural:SEED' or a path to a JSON file; `width` [m]
    overrides the path's own."""
    if width is not None:
        check_width(width, "--path-width")
    if isinstance(ref, dict):
        return path_from_spec(ref, width)
    if not isinstance(ref, (str, FilePath)):
        raise PathError(f"a path is an object, a preset name, procedural:SEED or a file, got {show(ref)}")
    ref = str(ref)
    if ref.startswith("procedural:"):
        text = ref.split(":", 1)[1]
        if not (text.isascii() and text.isdigit()) or len(text) > 19 or int(text) > MAX_SEED:
            raise PathError(f"{show(ref)}: the seed of a procedural path must be an integer from 0 to {MAX_SEED}")
        return path_from_spec(procedural_spec(int(text), width), ref=ref)
    if "/" not in ref and not ref.endswith(".json"):
        names = preset_names()
        if ref not in names:
            raise PathError(f"unknown path preset {show(ref)} (presets: {', '.join(names)}; or a .json file or "
                            f"procedural:SEED)")
        return path_from_spec(read_json(PATHS_DIR / f"{ref}.json", "path", error=PathError), width, ref=ref)
    data = read_json(FilePath(ref), "path", error=PathError)
    try:
        return path_from_spec(data, width, ref=ref)
    except PathError as e:
        raise PathError(f"{ref}: {e}") from None
