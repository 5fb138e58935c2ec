"""Procedural closed tracks from a seed.

A random chain of arcs whose turning angles sum to one full turn closes in heading by construction; two
straights of unknown length, chosen at headings far apart, then close it in position (a 2x2 linear solve).
Candidates that come out too short, too long, too tight or crossing themselves are drawn again.
"""
from __future__ import annotations

import math

import numpy as np

from sim.track.trackfile import MAX_LANES, TrackError, build_segments, chain_segments, track_from_spec


def close_with_straights(specs: list[dict], unknown: tuple[int, int]) -> list[dict] | None:
    """Fill the lengths of the two straights at indices `unknown` so that the chain closes in position.

    Returns the completed specs, or None when the two straights are (nearly) parallel or a length would be
    negative.
    """
    trial = [dict(s) for s in specs]
    for i in unknown:
        trial[i]["length"] = 1.0
    segs = build_segments(trial)
    x, y, _ = segs[-1].end_pose()
    dirs = [(math.cos(segs[i].heading0), math.sin(segs[i].heading0)) for i in unknown]
    # with unit lengths in place, end = K + e1 + e2; we need K + u1 e1 + u2 e2 = 0
    kx, ky = x - dirs[0][0] - dirs[1][0], y - dirs[0][1] - dirs[1][1]
    a = np.array([[dirs[0][0], dirs[1][0]], [dirs[0][1], dirs[1][1]]])
    if abs(np.linalg.det(a)) < 0.3:
        return None
    u = np.linalg.solve(a, [-kx, -ky])
    if (u <= 0).any():
        return None
    for i, length in zip(unknown, u):
        trial[i]["length"] = float(length)
    return trial


def close_loop(angles, radii, gaps) -> list[dict] | None:
    """Segment specs of a loop: a first straight, then arcs of the given angles [deg, positive left] and radii
    [m], each followed by a straight of its gap [m] (0: none). The first straight and the one whose direction is
    closest to perpendicular to it get the lengths that close the loop in position (the angles must add up to
    360). None when it cannot close (no second straight, parallel straights, a negative length). Procedural tracks
    and procedural sidewalk paths are drawn this way."""
    specs: list[dict] = [{"type": "straight", "length": None}]
    straight_at: list[int] = [0]
    for a, r, g in zip(angles, radii, gaps):
        specs.append({"type": "arc", "radius": round(float(r), 3), "angle_deg": round(abs(float(a)), 6),
                      "turn": "left" if a > 0 else "right"})
        if g > 0:
            straight_at.append(len(specs))
            specs.append({"type": "straight", "length": round(float(g), 3)})
    if len(straight_at) < 2:
        return None
    segs = chain_segments([{**s, "length": 1.0} if s.get("length", 1) is None else s for s in specs])
    other = max(straight_at[1:], key=lambda i: abs(math.sin(segs[i].heading0)))
    try:
        return close_with_straights(specs, (0, other))
    except ValueError:   # the track's segment check refused a piece (path-scale pieces it does not know)
        return None


def procedural_spec(seed: int, lanes: int = 3) -> dict:
    """A closed track spec drawn from `seed`; valid for every lane count up to MAX_LANES."""
    rng = np.random.default_rng([int(seed), 0x7AC])
    for _ in range(5000):
        n_arcs = int(rng.integers(4, 9))
        signs = np.where(rng.random(n_arcs) < 0.25, -1.0, 1.0)
        signs[0] = 1.0
        raw = rng.uniform(30.0, 140.0, n_arcs) * signs
        if raw.sum() < 90.0:
            continue
        angles = raw * 360.0 / raw.sum()
        if (np.abs(angles) < 15.0).any() or (np.abs(angles) > 200.0).any():
            continue
        radii = rng.uniform(45.0, 220.0, n_arcs)
        gaps = np.where(rng.random(n_arcs) < 0.3, 0.0, rng.uniform(20.0, 350.0, n_arcs))
        closed = close_loop(angles, radii, gaps)
        if closed is None:
            continue
        lengths = [s["length"] for s in closed if s["type"] == "straight"]
        if min(lengths) < 40.0 or max(lengths) > 1500.0:
            continue
        for s in closed:
            if s["type"] == "straight":
                s["length"] = round(s["length"], 4)
        spec = {"name": f"procedural-{seed}", "lanes": lanes, "lane_width": 4.0, "segments": closed}
        total = sum(s["length"] if s["type"] == "straight" else math.radians(s["angle_deg"]) * s["radius"]
                    for s in closed)
        if not 1000.0 <= total <= 6000.0:
            continue
        try:
            track_from_spec(spec, lanes=MAX_LANES)  # tightest cross-section: valid for fewer lanes too
        except TrackError:
            continue
        return spec
    raise TrackError(f"could not draw a valid procedural track from seed {seed}")

