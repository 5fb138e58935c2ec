"""The conditions' effects on the ground and the objects of a frame, compiled with numba (sim/render/effects.py
builds the tables read here and says what each effect is).

Where the renderer drew no object, a pixel shows the sky or the flat ground, the same in every frame: the sky is the
Look's and left as it is; on the ground the effect (the darkness and the host's headlights, the fog) is
`colour x gain(lit) x t + fog x (1 - t)` with the pixel's fog transmittance t and headlight `lit` stored once, a
byte each. Where the renderer drew an object (a finite depth) they come from its distance. The tables are bytes and
the rays are computed from each view's camera, so that what a frame reads stays in the processor's caches.

Arrays of pixels are flat (row after row), colours 3 a pixel. `cams` holds a row per view (effects.py CAMS).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

INF = np.float32(np.inf)
FINITE = np.float32(3e38)   # a depth under this is finite (fast maths may assume no infinity in a test against inf)
# fast maths, but not the flags that assume no infinities: an infinite depth means nothing was drawn there
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}
STEP = 4.0          # table entries per metre of the distance tables (fog, headlights)
TOP = np.float32(255.0)
LIT = 64.0          # the headlights' light in a byte: 64 is 1, a byte reaches 4
FAR = np.float32(1e6)   # [m] past every table's end (its index, at most 255 x STEP x this, fits a uint64)


@njit(cache=True, fastmath=FAST)
def headlight(px, py, pz, beam):
    """The host's low beams' light [0-1+] at a point (car frame [m]); beam: x, z [m] of the beams' source, reach
    [m], the cut-off's slope above which the beam fades, its fade, half width as a slope across."""
    qx = px - beam[0]
    if qx < 0.02 * beam[2]:   # behind the lamps, or at them
        return 0.0
    up = (pz - beam[1]) / qx - beam[3]
    across = py / qx / beam[5]
    vertical = 1.0 if up < 0.0 else math.exp(-(up / beam[4]) ** 2)
    r = qx / beam[2]
    return vertical * math.exp(-across * across) / (1.0 + r * r)


@njit(cache=True)
def ray(cams, v, r, c):
    """The ray of frame pixel (r, c) of view v in the car frame, per metre along the view's axis."""
    top, left, vh, vw = cams[v, 14], cams[v, 15], cams[v, 16], cams[v, 17]
    col = (vw - (c - left) - 0.5) if cams[v, 18] else (c - left + 0.5)
    x, y = (col - vw / 2) * cams[v, 22], (vh / 2 - (r - top + 0.5)) * cams[v, 23]
    return (x * cams[v, 3] + y * cams[v, 6] + cams[v, 9], x * cams[v, 4] + y * cams[v, 7] + cams[v, 10],
            x * cams[v, 5] + y * cams[v, 8] + cams[v, 11])


@njit(cache=True)
def beams(lit, cone, view, ground, cams, beam, width):
    """Per pixel, the headlights on the ground it shows and the beams' cone along its ray (headlight() at one reach
    over the falloff there: an object's light at distance d is about cone x falloff(d)), as bytes (LIT a unit)."""
    for p in range(view.shape[0]):
        v = view[p]
        if v < 0:
            continue
        rx, ry, rz = ray(cams, v, p // width, p % width)
        for d, out, scale in ((np.float64(ground[p]), lit, 1.0), (beam[2], cone, 2.0)):
            if d < np.inf:
                h = scale * headlight(cams[v, 0] + d * rx, cams[v, 1] + d * ry, cams[v, 2] + d * rz, beam)
                out[p] = np.uint8(min(255.0, round(h * LIT)))


# --- per frame -----------------------------------------------------------------------------------------------
@njit(cache=True, fastmath=FAST)
def _ground_run(out, src, fog, lit, gain, dark, fog_rgb):
    # one run of pixels, as arrays of their own (the compiler vectorises the loop only so)
    for i in range(fog.shape[0]):
        t = np.float32(fog[i]) * np.float32(1.0 / 255.0)
        h = np.float32(lit[i]) * np.float32(1.0 / LIT)
        u = np.float32(1.0) - t
        for c in range(3):
            out[3 * i + c] = np.uint8(min(src[3 * i + c] * (dark[c] + gain[c] * h) * t + fog_rgb[c] * u, TOP))


@njit(cache=True, fastmath=FAST)
def _fog_only(out, src, fog, dark, fog_rgb):
    # _ground_run without headlights (by day: their light 0, the colour x dark, 1 by day, x t exactly as there)
    for i in range(fog.shape[0]):
        t = np.float32(fog[i]) * np.float32(1.0 / 255.0)
        u = np.float32(1.0) - t
        for c in range(3):
            out[3 * i + c] = np.uint8(min(src[3 * i + c] * dark[c] * t + fog_rgb[c] * u, TOP))


@njit(cache=True, fastmath=FAST)
def _lit_only(out, src, lit, gain, dark):
    # _ground_run without fog (its byte 255: t is 1 exactly, its colour x 0)
    for i in range(lit.shape[0]):
        h = np.float32(lit[i]) * np.float32(1.0 / LIT)
        for c in range(3):
            out[3 * i + c] = np.uint8(min(src[3 * i + c] * (dark[c] + gain[c] * h), TOP))


@njit(cache=True, fastmath=FAST)
def ground(out, src, spans, fog, lit, gain, dark, fog_rgb):
    """Every pixel of src into out, the ground's (flat ranges `spans` (n, 2), in order) as colour x (dark + gain x
    lit) x t + fog_rgb x (1 - t), t the fog byte / 255, lit the headlights' byte / LIT; dark (3,): the night's light
    (1 by day), gain (3,): the headlights' colour (0 by day); the others as they are. No fog bytes: none (each
    255); no lit bytes: no headlights (each 0), so that neither is read where it changes nothing."""
    done = 0
    for k in range(spans.shape[0]):
        lo, hi = spans[k, 0], spans[k, 1]
        copy(out, src, np.uint64(3 * done), np.uint64(3 * lo))
        if fog.shape[0] and lit.shape[0]:
            _ground_run(out[3 * lo:3 * hi], src[3 * lo:3 * hi], fog[lo:hi], lit[lo:hi], gain, dark, fog_rgb)
        elif fog.shape[0]:
            _fog_only(out[3 * lo:3 * hi], src[3 * lo:3 * hi], fog[lo:hi], dark, fog_rgb)
        else:
            _lit_only(out[3 * lo:3 * hi], src[3 * lo:3 * hi], lit[lo:hi], gain, dark)
        done = hi
    copy(out, src, np.uint64(3 * done), np.uint64(src.shape[0]))


@njit(cache=True, error_model="numpy")
def falloff(d, last, reach):
    """The headlights' falloff at a distance d [m] as Effects' table has it (STEP entries a metre, the last at
    index `last`, for a beam of `reach` [m]): 1 / (1 + (x / reach)^2) at d's entry's x = k / STEP, in float32.
    Strict maths (no fast flags): numpy's operations in numpy's order, so the table's very value."""
    x = min(np.floor(d * STEP), last) / STEP
    q = x / reach
    return np.float32(1.0 / (1.0 + q * q))


@njit(cache=True)
def copy(out, src, lo, hi):
    """src[lo:hi] into out[lo:hi] (lo, hi unsigned: a loop the compiler turns into a block copy; numba's slice
    assignment copies a byte at a time)."""
    for i in range(lo, hi):
        out[i] = src[i]


@njit(cache=True, fastmath=FAST)
def _extent(row):
    # the first and the end of the finite depths of a row of at most 32,767 pixels; (n, n) where none. The positions
    # are int16: the compiler vectorises the loop 16 pixels at a time (twice as fast as with 64-bit positions)
    n = np.int16(row.shape[0])
    first, last = n, np.int16(0)
    for i in range(row.shape[0]):
        finite = row[i] < FINITE
        first = min(first, np.int16(i) if finite else n)
        last = max(last, np.int16(i + 1) if finite else np.int16(0))
    return first, max(first, last)


@njit(cache=True, fastmath=FAST)
def objects(out, src, depth, view, width, reach, cams, cone, fall, fog, dark, gain, fog_rgb, lamps, radius, lamp_rgb,
            wet, row_view, segments, beam_reach):
    """The pixels where an object was drawn (depth finite), found between each row's first and last: drawn (_shade at
    night, _by_day by day on a wet road, _dry_day on a dry one), then mirrored by a wet road (_by_day; wet: contact,
    wetness, road, tall, near, one_view), row by row, top down. The insets' borders have no depth. row_view: per row,
    the one view its pixels show (-1: several); segments: the runs of a row's pixels of one view (_by_day); beam_reach:
    the reach [m] the falloff table `fall` was built with. Each helper is called once, not once a row: a call copies the
    references to its arrays."""
    extents = np.empty((depth.shape[0] // width, 2), dtype=np.uint64)
    for r in range(extents.shape[0]):
        first, end = _extent(depth[r * width:(r + 1) * width])
        extents[r, 0], extents[r, 1] = np.uint64(r * width + first), np.uint64(r * width + end)
    night = fall.shape[0] > 1
    if night:
        _shade(out, src, depth, view, width, extents, reach, cams, cone, fall, fog, dark, gain, fog_rgb, lamps, radius,
               lamp_rgb, row_view, beam_reach)
    contact, wetness, road, tall, near, one_view = wet
    if contact.shape[1] > 1:
        _by_day(out, src, depth, view, width, extents, reach, fog, fog_rgb, contact, wetness, road, tall, near,
                one_view, segments, not night)
    elif not night:
        _dry_day(out, src, depth, width, extents, reach, fog, fog_rgb)


@njit(cache=True, fastmath=FAST)
def _dry_day(out, src, depth, width, extents, reach, fog, fog_rgb):
    """By day on a dry road, the object pixels between extents[r] (first, end: unsigned) of each row r, as _by_day
    draws them, in two loops the compiler vectorises (the fog read, the colours drawn): without a reflection to draw
    as each pixel is drawn they cost less than _by_day's one."""
    t = np.ones(width)
    for r in range(extents.shape[0]):
        lo, hi = extents[r, 0], extents[r, 1]
        if hi > lo:
            if fog.shape[0] > 1:
                _fog_run(t, depth[lo:hi], reach[lo:hi], fog)
            _day_run(out[3 * lo:3 * hi], src[3 * lo:3 * hi], depth[lo:hi], t, fog_rgb)


@njit(cache=True, fastmath=FAST)
def _day_run(out, src, depth, t, fog_rgb):
    # one row's pixels between its first and last object pixel by day, as _shade_run without headlights or lamps
    # and with the light of day (dark 1: its product left out, exactly)
    f0, f1, f2 = np.float64(fog_rgb[0]), np.float64(fog_rgb[1]), np.float64(fog_rgb[2])
    for i in range(depth.shape[0]):
        t0 = t[i]
        u = 1.0 - t0
        keep = np.uint8(depth[i] >= FINITE) * np.uint8(255)   # all ones where no object: the byte kept
        c0 = np.uint8(min(src[3 * i] * t0 + f0 * u, 255.0))
        c1 = np.uint8(min(src[3 * i + 1] * t0 + f1 * u, 255.0))
        c2 = np.uint8(min(src[3 * i + 2] * t0 + f2 * u, 255.0))
        out[3 * i] = (out[3 * i] & keep) | (c0 & ~keep)
        out[3 * i + 1] = (out[3 * i + 1] & keep) | (c1 & ~keep)
        out[3 * i + 2] = (out[3 * i + 2] & keep) | (c2 & ~keep)


@njit(cache=True, fastmath=FAST)
def _shade(out, src, depth, view, width, extents, reach, cams, cone, fall, fog, dark, gain, fog_rgb, lamps, radius,
           lamp_rgb, row_view, beam_reach):
    """At night, the object pixels of each row r between extents[r] (first, end: unsigned), from the renderer's
    colour and the object's distance d along the view's axis: colour x (dark + gain x cone fall[d] + lamp_rgb x
    pools) x t + fog_rgb x (1 - t), t = fog[d x STEP x the ray's length] (reach: the length in 128ths, a byte a
    pixel; the tables STEP a metre), pools: the street lamps' (lamps (n, 2 + views): x, y [m, car frame], then the
    distance along each view's axis of the pool's centre; `radius` [m] their radius). A row in three loops over its
    pixels: the tables read (t, the headlights' light), the pools summed (in a row of one view (row_view) a lamp at
    a time: _row_pools, a loop the compiler vectorises; the same sums in the same order as a pixel's own loop over
    the lamps), and the colours drawn (_shade_run, vectorised too). By day _by_day draws them."""
    nf, nl = np.uint64(fall.shape[0] - 1), np.uint64(fog.shape[0] - 1)
    cols = np.empty((3, 4))   # per channel: dark, gain, lamp_rgb, fog_rgb
    for c in range(3):
        cols[c, 0], cols[c, 1], cols[c, 2], cols[c, 3] = dark[c], gain[c], lamp_rgb[c], fog_rgb[c]
    pool, lit, t = np.zeros(width), np.zeros(width), np.ones(width)
    at_x, at_y = np.empty(width), np.empty(width)
    for r in range(extents.shape[0]):
        lo, hi = extents[r, 0], extents[r, 1]
        if hi == lo:
            continue
        if _lit_any(cone[lo:hi]):
            _lit_run(lit, depth[lo:hi], cone[lo:hi], np.float64(nf), beam_reach)
        else:   # out of the beams' cone: no light (cone 0 x the falloff, which is finite)
            for i in range(hi - lo):
                lit[i] = 0.0
        if nl > 0:
            _fog_run(t, depth[lo:hi], reach[lo:hi], fog)
        if nf > 0 and lamps.shape[0] and row_view[r] >= 0:
            _row_pools(pool, at_x, at_y, depth[lo:hi], r, np.int64(lo) - r * width, row_view[r], cams, lamps, radius)
        elif nf > 0 and lamps.shape[0]:
            for p in range(lo, hi):
                d = depth[p]
                sum_ = 0.0
                if d < FINITE:
                    rx = ry = np.inf
                    v = view[p]
                    for j in range(lamps.shape[0]):   # the street lamps' pools
                        if abs(d - lamps[j, 2 + v]) > radius:   # farther along the view's axis than the pool reaches
                            continue
                        if rx == np.inf:   # the ray, once for the lamps near enough
                            rx, ry, _ = ray(cams, v, r, np.int64(p) - r * width)
                        dx, dy = cams[v, 0] + d * rx - lamps[j, 0], cams[v, 1] + d * ry - lamps[j, 1]
                        f = max(0.0, 1.0 - (dx * dx + dy * dy) / (radius * radius))
                        sum_ += f * f
                pool[p - lo] = sum_
        if nl > 0:
            _shade_run(out[3 * lo:3 * hi], src[3 * lo:3 * hi], depth[lo:hi], t, lit, pool, cols)
        else:
            _unfogged_run(out[3 * lo:3 * hi], src[3 * lo:3 * hi], depth[lo:hi], lit, pool, cols)


@njit(cache=True, fastmath=FAST)
def _by_day(out, src, depth, view, width, extents, reach, fog, fog_rgb, contact, wetness, road, tall, near, one_view,
            segments, shade):
    """On a wet road by day (shade) the object pixels between extents[r] (first, end: unsigned) of each row r, as _shade
    draws them in the light of day (dark 1: its product left out) without headlights or lamps, in one loop, each
    mirrored as soon as it is drawn (the reflection's loads overlap the drawing: it costs less than _dry_day's loops and
    a loop of reflections); at night (not shade: _shade draws them) only mirrored. segments (n, 4): the runs of a row's
    pixels of one view (flat index of the first, of the end; view; row), row by row, left to right. A pixel of view v at
    distance d shows again at row 2 g - r, g = contact[v, d STEP] (the row of the ground at that distance, -1: none; a
    contact of one entry: a dry road), blended in by wetness[v, that row] where the renderer drew the asphalt (colour
    `road`, within a level) and no object; tall: rows x metres above its ground row beyond which a pixel is not mirrored
    (a car's height x the focal length: not the crowns of trees); near (views, rows, 2): the distances [m] outside which
    no pixel of a row is mirrored, tested first; one_view: every pixel of the frame is of view 0 (no insets: the view is
    not read). A reflection falls on a pixel of the ground, drawn (ground) and drawn on by no object: a row's
    reflections drawn with the row are what they are drawn after every row."""
    # unsigned indices throughout, and the view's rows of contact and wetness taken once a run: numba tests a signed
    # index for wrapping around at each access
    nl, one, two, three = np.uint64(fog.shape[0] - 1), np.uint64(1), np.uint64(2), np.uint64(3)
    wetted = contact.shape[1] > 1
    nc, height = np.uint64(contact.shape[1] - 1), view.shape[0] // width
    f0, f1, f2 = np.float64(fog_rgb[0]), np.float64(fog_rgb[1]), np.float64(fog_rgb[2])
    r0, r1, r2 = road[0], road[1], road[2]
    for k in range(segments.shape[0]):
        v, r = segments[k, 2], segments[k, 3]
        lo, hi = max(np.uint64(segments[k, 0]), extents[r, 0]), min(np.uint64(segments[k, 1]), extents[r, 1])
        dlo, dhi = (near[v, r, 0], near[v, r, 1]) if wetted else (0.0, 0.0)   # where a pixel can be mirrored
        ground_rows, wet_rows = contact[v], wetness[v]
        for p in range(lo, hi):
            d = depth[p]
            if d >= FINITE:
                continue
            q = three * p
            if shade:
                t0, u = 1.0, 0.0
                if nl > 0:
                    t0 = np.float64(fog[min(np.uint64(d * np.float32(reach[p]) * np.float32(STEP / 128.0)), nl)])
                    u = 1.0 - t0
                out[q] = np.uint8(min(src[q] * t0 + f0 * u, 255.0))
                out[q + one] = np.uint8(min(src[q + one] * t0 + f1 * u, 255.0))
                out[q + two] = np.uint8(min(src[q + two] * t0 + f2 * u, 255.0))
            if not dlo <= d < dhi:
                continue
            g = ground_rows[min(np.uint64(d * STEP), nc)]
            target = 2 * g - r
            if g < 0 or (g - r) * d > tall or target <= r or target >= height:
                continue
            at = np.uint64(np.int64(p) + (target - r) * width)
            b = three * at
            # the asphalt drawn there, within a level, no object and the same view (one test, not five branches)
            if (abs(np.int64(src[b]) - r0) <= 1) & (abs(np.int64(src[b + one]) - r1) <= 1) & \
                    (abs(np.int64(src[b + two]) - r2) <= 1) & (depth[at] >= FINITE) & (one_view or view[at] == v):
                a = wet_rows[np.uint64(target)]
                for c in (np.uint64(0), one, two):
                    x = np.float32(out[b + c])
                    out[b + c] = np.uint8(x + a * (np.float32(out[q + c]) - x))


@njit(cache=True)
def _lit_any(cone):
    # whether any pixel of a run is in the beams' cone (a loop the compiler vectorises)
    most = np.uint8(0)
    for i in range(cone.shape[0]):
        most = max(most, cone[i])
    return most > 0


@njit(cache=True, error_model="numpy")   # no test for a division by zero: the loop is vectorised only so
def _lit_run(lit, depth, cone, last, beam_reach):
    # the headlights' light of a row's pixels, as arrays of their own: the falloff computed (strict maths), not
    # read from its table, so that the compiler vectorises the loop (an infinite depth: capped at FAR, where the
    # falloff is the table's last entry's)
    for i in range(depth.shape[0]):
        lit[i] = cone[i] * (1.0 / LIT) * falloff(min(depth[i], FAR), last, beam_reach)


@njit(cache=True, fastmath=FAST)
def _fog_run(t, depth, reach, fog):
    # the fog's transmittance of a row's pixels, as _lit_run
    nl = np.uint64(fog.shape[0] - 1)
    for i in range(depth.shape[0]):
        d = min(depth[i], FAR)
        t[i] = np.float64(fog[min(np.uint64(d * np.float32(reach[i]) * np.float32(STEP / 128.0)), nl)])


@njit(cache=True, fastmath=FAST)
def _shade_run(out, src, depth, t, lit, pool, cols):
    # one row's pixels between its first and last object pixel, as arrays of their own (the compiler vectorises the
    # loop only so); the others (an infinite depth) as they are
    d0, d1, d2, k0, k1, k2 = cols[0, 0], cols[1, 0], cols[2, 0], cols[0, 1], cols[1, 1], cols[2, 1]
    l0, l1, l2, f0, f1, f2 = cols[0, 2], cols[1, 2], cols[2, 2], cols[0, 3], cols[1, 3], cols[2, 3]
    for i in range(depth.shape[0]):
        h, s, ti = lit[i], pool[i], t[i]
        u = 1.0 - ti
        keep = np.uint8(depth[i] >= FINITE) * np.uint8(255)   # all ones where no object: the byte kept
        c0 = np.uint8(min(src[3 * i] * (d0 + (k0 * h + l0 * s)) * ti + f0 * u, 255.0))
        c1 = np.uint8(min(src[3 * i + 1] * (d1 + (k1 * h + l1 * s)) * ti + f1 * u, 255.0))
        c2 = np.uint8(min(src[3 * i + 2] * (d2 + (k2 * h + l2 * s)) * ti + f2 * u, 255.0))
        out[3 * i] = (out[3 * i] & keep) | (c0 & ~keep)
        out[3 * i + 1] = (out[3 * i + 1] & keep) | (c1 & ~keep)
        out[3 * i + 2] = (out[3 * i + 2] & keep) | (c2 & ~keep)


@njit(cache=True, fastmath=FAST)
def _unfogged_run(out, src, depth, lit, pool, cols):
    # _shade_run without fog: its transmittance 1, its colour x 0 (the same bytes, the fog's terms not read)
    d0, d1, d2, k0, k1, k2 = cols[0, 0], cols[1, 0], cols[2, 0], cols[0, 1], cols[1, 1], cols[2, 1]
    l0, l1, l2 = cols[0, 2], cols[1, 2], cols[2, 2]
    for i in range(depth.shape[0]):
        h, s = lit[i], pool[i]
        keep = np.uint8(depth[i] >= FINITE) * np.uint8(255)   # all ones where no object: the byte kept
        c0 = np.uint8(min(src[3 * i] * (d0 + (k0 * h + l0 * s)), 255.0))
        c1 = np.uint8(min(src[3 * i + 1] * (d1 + (k1 * h + l1 * s)), 255.0))
        c2 = np.uint8(min(src[3 * i + 2] * (d2 + (k2 * h + l2 * s)), 255.0))
        out[3 * i] = (out[3 * i] & keep) | (c0 & ~keep)
        out[3 * i + 1] = (out[3 * i + 1] & keep) | (c1 & ~keep)
        out[3 * i + 2] = (out[3 * i + 2] & keep) | (c2 & ~keep)


@njit(cache=True, fastmath=FAST)
def _row_pools(pool, at_x, at_y, depth, r, c0, v, cams, lamps, radius):
    """The street lamps' pools (lamps as _shade has them) summed into pool[:n] for the n pixels of depth, row r of
    view v from column c0 (at_x, at_y: room for the points they show): each lamp's (1 - distance^2 / radius^2)^2
    where that is positive and the pixel is within `radius` of the pool's centre along the view's axis, lamp after
    lamp (as _shade adds them a pixel)."""
    n = depth.shape[0]
    for i in range(n):   # the point each pixel shows, once for all the lamps
        pool[i] = 0.0
        rx, ry, _ = ray(cams, v, r, c0 + i)
        at_x[i], at_y[i] = cams[v, 0] + depth[i] * rx, cams[v, 1] + depth[i] * ry
    for j in range(lamps.shape[0]):
        lx, ly, ld = lamps[j, 0], lamps[j, 1], lamps[j, 2 + v]
        for i in range(n):
            d = depth[i]
            dx, dy = at_x[i] - lx, at_y[i] - ly
            f = max(0.0, 1.0 - (dx * dx + dy * dy) / (radius * radius))
            pool[i] += f * f if abs(d - ld) <= radius else 0.0


@njit(cache=True, fastmath=FAST)
def _pool_run(out, src, depth, ex, ey, bx, by, r2, rgb3, f3):
    # one row's pixels inside one disc, as arrays of their own (the compiler vectorises the loops only so): the
    # disc's light a pixel, 3 times over (f3), then the bytes in a row, the colour's channels repeated in rgb3 (a
    # loop over the bytes runs faster than one over the pixels and their 3 channels)
    for i in range(depth.shape[0]):
        dx, dy = ex + i * bx, ey + i * by
        f = max(0.0, 1.0 - (dx * dx + dy * dy) / r2)
        f = f * f * (depth[i] == INF)
        f3[3 * i], f3[3 * i + 1], f3[3 * i + 2] = f, f, f
    for k in range(out.shape[0]):
        out[k] = np.uint8(min(TOP, out[k] + src[k] * f3[k] * rgb3[k]))


@njit(cache=True, fastmath=FAST)
def pools(out, src, depth, rows, spots, lamps, reach, rgb):
    """The street lamps' pools of light on the ground, added where no object was drawn: each a smooth disc of
    radius `reach` [m] around its centre (lamps (n, 2) [m, car frame]), lighting the renderer's colour by rgb at its
    middle. rows (n, 2): the ground's row segments (flat index of the first pixel, of the end), spots (n, 4): the
    car-frame point [m] of the first pixel's ground and its step a pixel along the row (a row's ground points lie
    on a line): only the pixels inside a disc are visited."""
    r2 = reach * reach
    n = 0
    for k in range(rows.shape[0]):
        n = max(n, rows[k, 1] - rows[k, 0])
    f3, rgb3 = np.empty(3 * n), np.empty(3 * n)
    for i in range(n):
        rgb3[3 * i], rgb3[3 * i + 1], rgb3[3 * i + 2] = rgb[0], rgb[1], rgb[2]
    for k in range(rows.shape[0]):
        p0, p1 = rows[k, 0], rows[k, 1]
        ax, ay, bx, by = spots[k, 0], spots[k, 1], spots[k, 2], spots[k, 3]
        bb = bx * bx + by * by
        for j in range(lamps.shape[0]):
            ex, ey = ax - lamps[j, 0], ay - lamps[j, 1]
            half = bx * ex + by * ey
            disc = half * half - bb * (ex * ex + ey * ey - r2)   # |e + i b|^2 < r2 for i between the roots
            if disc <= 0.0 or bb == 0.0:
                continue
            root = math.sqrt(disc)
            lo = max(p0, p0 + int(math.ceil((-half - root) / bb)))
            hi = min(p1, p0 + int((-half + root) / bb) + 1)
            if hi > lo:
                i = lo - p0
                _pool_run(out[3 * lo:3 * hi], src[3 * lo:3 * hi], depth[lo:hi], ex + i * bx, ey + i * by, bx, by,
                          r2, rgb3, f3)
