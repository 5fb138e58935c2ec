"""The conditions' effects take shortcuts that leave work out where it changes no byte (issue 49: a condition's frame
within 20 % of clear's): each draws what the long way draws, on random frames."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.render.effect_kernels import FAST, STEP, _by_day, _dry_day, _lit_any, _lit_run, _shade_run, _unfogged_run
from sim.render.light_kernels import glow, project

WIDTH, HEIGHT = 64, 48


def _frame(rng, objects: float = 0.4):
    """A random frame: colours, depths (inf where no object), rays' lengths (reach bytes)."""
    src = rng.integers(0, 256, HEIGHT * WIDTH * 3).astype(np.uint8)
    depth = np.where(rng.random(HEIGHT * WIDTH) < objects, rng.uniform(0.5, 300.0, HEIGHT * WIDTH),
                     np.inf).astype(np.float32)
    reach = rng.integers(128, 180, HEIGHT * WIDTH).astype(np.uint8)
    return src, depth, reach


def _extents(depth):
    """Each row's first and last finite depth, as objects() finds them."""
    out = np.empty((HEIGHT, 2), dtype=np.uint64)
    for r, row in enumerate(depth.reshape(HEIGHT, WIDTH)):
        finite = np.flatnonzero(np.isfinite(row))
        out[r] = (r * WIDTH + finite[0], r * WIDTH + finite[-1] + 1) if len(finite) else ((r + 1) * WIDTH,) * 2
    return out


def test_a_dry_roads_object_pixels_by_day_are_the_wet_loops():
    """_dry_day's loops (the fog read, then the colours) draw what _by_day's one loop draws on a dry road."""
    rng = np.random.default_rng(0)
    view = np.zeros(HEIGHT * WIDTH, dtype=np.int8)
    segments = np.array([(r * WIDTH, (r + 1) * WIDTH, 0, r) for r in range(HEIGHT)], dtype=np.int64)
    dry = (np.full((1, 1), -1, dtype=np.int64), np.zeros((1, 1), dtype=np.float32))
    for density in (0.0, 0.004, 0.03):
        fog = (np.exp(-density * np.arange(int(400 * STEP) + 1) / STEP) if density else np.ones(1)).astype(np.float32)
        fog_rgb = rng.uniform(100.0, 220.0, 3).astype(np.float32)
        for _ in range(5):
            src, depth, reach = _frame(rng)
            extents = _extents(depth)
            want = rng.integers(0, 256, src.shape).astype(np.uint8)
            got = want.copy()
            _by_day(want, src, depth, view, WIDTH, extents, reach, fog, fog_rgb, *dry, np.zeros(3, dtype=np.int64),
                    0.0, np.zeros((1, HEIGHT, 2)), True, segments, True)
            _dry_day(got, src, depth, WIDTH, extents, reach, fog, fog_rgb)
            assert np.array_equal(got, want), density


def test_the_nights_object_pixels_without_fog_are_those_with_a_clear_fog():
    """Without fog _unfogged_run draws what _shade_run draws with the fog's transmittance 1 everywhere."""
    rng = np.random.default_rng(1)
    cols = np.c_[rng.uniform(0.05, 0.2, 3), rng.uniform(0.5, 0.9, 3), rng.uniform(0.3, 0.5, 3), rng.uniform(0, 255, 3)]
    for _ in range(20):
        src, depth, _ = _frame(rng)
        lit = rng.uniform(0.0, 4.0, depth.shape[0]) * (rng.random(depth.shape[0]) < 0.7)
        pool = rng.uniform(0.0, 2.0, depth.shape[0]) * (rng.random(depth.shape[0]) < 0.5)
        want = rng.integers(0, 256, src.shape).astype(np.uint8)
        got = want.copy()
        _shade_run(want, src, depth, np.ones(depth.shape[0]), lit, pool, cols)
        _unfogged_run(got, src, depth, lit, pool, cols)
        assert np.array_equal(got, want)


def test_a_run_out_of_the_beams_cone_has_no_headlight():
    """A run whose cone bytes are all 0 is left without its falloff computed: the light computed there is 0."""
    rng = np.random.default_rng(2)
    depth = np.r_[rng.uniform(0.0, 400.0, 500), np.inf].astype(np.float32)
    lit = np.full(depth.shape[0], np.nan)
    cone = np.zeros(depth.shape[0], dtype=np.uint8)
    _lit_run(lit, depth, cone, 1600.0, 29.1)
    assert not _lit_any(cone) and np.array_equal(lit, np.zeros_like(lit))
    cone[rng.integers(0, cone.shape[0])] = 1
    assert _lit_any(cone)


@njit(cache=False, fastmath=FAST)
def _long_glow(out, depth, view, cams, v, px, py, pz, radius, rgb, strength, fog, streak, across):
    # glow() as drawn before its shortcuts: every pixel of its square's rows read
    col, row, d = project(cams, v, px, py, pz)
    if d < 0.0 or d > cams[v, 21]:
        return
    ic, ir = int(math.floor(col)), int(math.floor(row))
    top, left, vh, vw = int(cams[v, 14]), int(cams[v, 15]), int(cams[v, 16]), int(cams[v, 17])
    if not (top <= ir < top + vh and left <= ic < left + vw) or view[ir, ic] != v or depth[ir, ic] < d - 1.0:
        return
    rad = max(0.6, radius * cams[v, 13] / d)
    s = strength * (math.exp(-fog * d) if fog > 0.0 else 1.0)
    peak = s * max(rgb[0], rgb[1], rgb[2])
    if peak < 1.0:
        return
    q_max = min(9.0, math.log(peak))
    reach = int(math.ceil(rad * math.sqrt(q_max)))
    below = int(math.ceil(rad * math.sqrt(q_max) * streak))
    c0, c1 = max(left, ic - reach), min(left + vw, ic + reach + 1)
    for c in range(c0, c1):
        dx = (c + 0.5 - col) / rad
        across[c - c0] = math.exp(-dx * dx) if dx * dx < q_max else 0.0
    for r in range(max(top, ir - reach), min(top + vh, ir + reach + below + 1)):
        dy = (r + 0.5 - row) / rad
        if dy > 0.0 and streak > 0.0:
            dy = dy / (1.0 + streak)
        if dy * dy >= q_max:
            continue
        up = s * math.exp(-dy * dy)
        for c in range(c0, c1):
            if view[r, c] == v and across[c - c0] > 0.0:
                g = up * across[c - c0]
                for i in range(3):
                    out[r, c, i] = np.uint8(min(255.0, out[r, c, i] + g * rgb[i]))


def test_a_glow_leaves_the_pixels_it_lights_by_less_than_a_level_as_they_are():
    """A glow's pixels read and written one by one (unsigned flat indices), those it would light by less than a
    level left unread: the frame is the one every pixel of its square's rows drawn gives, near and far, in fog and
    with a wet road's streak, over two views."""
    rng = np.random.default_rng(3)
    h, w = 90, 120
    cams = np.zeros((2, 24))
    for v, (left, mirrored) in enumerate(((0, 0.0), (60, 1.0))):   # two views side by side, the second mirrored
        cams[v, 4], cams[v, 8], cams[v, 9] = -1.0, 1.0, 1.0   # right: -y, up: z, forward: x (car frame)
        cams[v, 2], cams[v, 12], cams[v, 13] = 1.2, 60.0, 60.0
        cams[v, 14:19] = 0, left, h, 60, mirrored
        cams[v, 19], cams[v, 21] = 0.1, 200.0
    view = np.zeros((h, w), dtype=np.int8)
    view[:, 60:] = 1
    view[:, 59:61] = -1   # a border between them
    across = np.empty(w)
    drawn = 0
    for _ in range(60):
        frame = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)
        depth = np.where(rng.random((h, w)) < 0.2, rng.uniform(1.0, 100.0, (h, w)), np.inf).astype(np.float32)
        want, got = frame.copy(), frame.copy()
        px, py, pz = rng.uniform(2.0, 80.0), rng.uniform(-3.0, 3.0), rng.uniform(0.3, 2.0)
        rgb = rng.uniform(20.0, 255.0, 3)
        args = (depth, view, cams, int(rng.integers(0, 2)), px, py, pz, rng.uniform(0.1, 0.4), rgb,
                rng.uniform(0.2, 1.0), float(rng.choice([0.0, 0.02])), float(rng.choice([0.0, 1.0])), across)
        _long_glow(want, *args)
        glow(got, *args)
        assert np.array_equal(got, want)
        drawn += not np.array_equal(got, frame)
    assert drawn > 30
