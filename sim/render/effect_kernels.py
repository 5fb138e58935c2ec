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
def ground(out, src, spans, fog, lit, gain, dark, fog_rgb):
    """Every pixel of src into out, the ground's (flat ranges `spans` (n, 2), in order) as colour x (dark + gain x
    lit) x t + fog_rgb x (1 - t), t the fog byte / 255, lit the headlights' byte / LIT; dark (3,): the night's light
    (1 by day), gain (3,): the headlights' colour (0 by day); the others as they are."""
    done = 0
    for k in range(spans.shape[0]):
        lo, hi = spans[k, 0], spans[k, 1]
        copy(out, src, np.uint64(3 * done), np.uint64(3 * lo))
        _ground_run(out[3 * lo:3 * hi], src[3 * lo:3 * hi], fog[lo:hi], lit[lo:hi], gain, dark, fog_rgb)
        done = hi
    copy(out, src, np.uint64(3 * done), np.uint64(src.shape[0]))


@njit(cache=True)
def copy(out, src, lo, hi):
    """src[lo:hi] into out[lo:hi] (lo, hi unsigned: a loop the compiler turns into a block copy; numba's slice
    assignment copies a byte at a time)."""
    for i in range(lo, hi):
        out[i] = src[i]


@njit(cache=True, fastmath=FAST)
def _extent(depth, lo, hi):
    # the first and the end of the finite depths of [lo, hi) (lo, hi unsigned: the compiler vectorises the loop only
    # so); (hi, hi) where none
    first, last = hi, lo
    for i in range(lo, hi):
        finite = depth[i] < FINITE
        first = min(first, i if finite else hi)
        last = max(last, i + np.uint64(1) if finite else lo)
    return first, max(first, last)


@njit(cache=True, fastmath=FAST)
def objects(out, src, depth, view, width, reach, cams, cone, fall, fog, dark, gain, fog_rgb, lamps, radius, lamp_rgb,
            contact, wetness, road, tall, row_view):
    """The pixels where an object was drawn (depth finite), found between each row's first and last: drawn
    (_shade), then mirrored by a wet road (_reflect; contact of one entry: a dry road), row by row, top down. A
    reflection falls on a pixel of the ground, drawn (ground) and drawn on by no object. The insets' borders have no
    depth. row_view: per row, the one view its pixels show (-1: several). Each helper is called once, not once a
    row: a call copies the references to its arrays."""
    extents = np.empty((depth.shape[0] // width, 2), dtype=np.uint64)
    for r in range(extents.shape[0]):
        extents[r] = _extent(depth, np.uint64(r * width), np.uint64((r + 1) * width))
    _shade(out, src, depth, view, width, extents, reach, cams, cone, fall, fog, dark, gain, fog_rgb, lamps, radius,
           lamp_rgb, row_view)
    if contact.shape[1] > 1:
        _reflect(out, src, depth, view, width, extents, contact, wetness, road, tall)


@njit(cache=True, fastmath=FAST)
def _shade(out, src, depth, view, width, extents, reach, cams, cone, fall, fog, dark, gain, fog_rgb, lamps, radius,
           lamp_rgb, row_view):
    """The object pixels of each row r between extents[r] (first, end: unsigned), from the renderer's colour and
    the object's distance d along the view's axis: colour x (dark + gain x cone fall[d] + lamp_rgb x pools) x t +
    fog_rgb x (1 - t), t = fog[d x STEP x the ray's length] (reach: the length in 128ths, a byte a pixel; the tables
    STEP a metre; fall of one entry: no headlights), pools: the street lamps' (lamps (n, 2 + views): x, y [m, car
    frame], then the distance along each view's axis of the pool's centre; `radius` [m] their radius). The colours
    are read into locals first: the compiler cannot tell that writing `out` leaves them unchanged. In a row of one
    view (row_view) the pools are summed first for the whole row, a lamp at a time (_row_pools: a loop the compiler
    vectorises), the same sums in the same order as a pixel's own loop over the lamps."""
    nf, nl = np.uint64(fall.shape[0] - 1), np.uint64(fog.shape[0] - 1)
    d0, d1, d2 = np.float64(dark[0]), np.float64(dark[1]), np.float64(dark[2])
    k0, k1, k2 = np.float64(gain[0]), np.float64(gain[1]), np.float64(gain[2])
    l0, l1, l2 = lamp_rgb[0], lamp_rgb[1], lamp_rgb[2]
    f0, f1, f2 = np.float64(fog_rgb[0]), np.float64(fog_rgb[1]), np.float64(fog_rgb[2])
    three = np.uint64(3)
    pools_ = np.empty(width)
    for r in range(extents.shape[0]):
        lo, hi = extents[r, 0], extents[r, 1]
        whole = nf > 0 and lamps.shape[0] > 0 and row_view[r] >= 0 and hi > lo
        if whole:
            _row_pools(pools_, depth[lo:hi], r, np.int64(lo) - r * width, row_view[r], cams, lamps, radius)
        for p in range(lo, hi):
            d = depth[p]
            if d >= FINITE:
                continue
            g0, g1, g2 = d0, d1, d2
            if nf > 0:
                h = cone[p] * (1.0 / LIT) * fall[min(np.uint64(d * STEP), nf)]
                pool = pools_[p - lo] if whole else 0.0
                rx = ry = np.inf
                v = view[p] if lamps.shape[0] else 0
                for j in range(0 if whole else lamps.shape[0]):   # the street lamps' pools
                    if abs(d - lamps[j, 2 + v]) > radius:   # farther along the view's axis than the pool reaches
                        continue
                    if rx == np.inf:   # the ray, once for the lamps near enough
                        rx, ry, _ = ray(cams, v, r, np.int64(p) - r * width)
                    dx, dy = cams[v, 0] + d * rx - lamps[j, 0], cams[v, 1] + d * ry - lamps[j, 1]
                    f = max(0.0, 1.0 - (dx * dx + dy * dy) / (radius * radius))
                    pool += f * f
                g0 += k0 * h + l0 * pool
                g1 += k1 * h + l1 * pool
                g2 += k2 * h + l2 * pool
            t, u = 1.0, 0.0
            if nl > 0:
                t = np.float64(fog[min(np.uint64(d * np.float32(reach[p]) * np.float32(STEP / 128.0)), nl)])
                u = 1.0 - t
            q = three * p
            out[q] = np.uint8(min(src[q] * g0 * t + f0 * u, 255.0))
            out[q + 1] = np.uint8(min(src[q + 1] * g1 * t + f1 * u, 255.0))
            out[q + 2] = np.uint8(min(src[q + 2] * g2 * t + f2 * u, 255.0))


@njit(cache=True, fastmath=FAST)
def _row_pools(pool, depth, r, c0, v, cams, lamps, radius):
    """The street lamps' pools (lamps as _shade has them) summed into pool[:n] for the n pixels of depth, row r of
    view v from column c0: each lamp's (1 - distance^2 / radius^2)^2 where that is positive and the pixel is within
    `radius` of the pool's centre along the view's axis, lamp after lamp (as _shade adds them a pixel)."""
    n = depth.shape[0]
    for i in range(n):
        pool[i] = 0.0
    for j in range(lamps.shape[0]):
        lx, ly, ld = lamps[j, 0], lamps[j, 1], lamps[j, 2 + v]
        for i in range(n):
            d = depth[i]
            rx, ry, _ = ray(cams, v, r, c0 + i)
            dx, dy = cams[v, 0] + d * rx - lx, cams[v, 1] + d * ry - ly
            f = max(0.0, 1.0 - (dx * dx + dy * dy) / (radius * radius))
            pool[i] += f * f if abs(d - ld) <= radius else 0.0


@njit(cache=True, fastmath=FAST)
def _reflect(out, src, depth, view, width, extents, contact, wetness, road, tall):
    """A wet road mirrors the objects standing on it: an object pixel of row r (between extents[r]), at distance d,
    shows again at row 2 contact[v, d STEP] - r (contact: per view, the row of the ground at each distance along its
    axis, -1 where none), blended in by wetness[v, that row] where the renderer drew the asphalt there (colour
    `road`, within a level) and no object; tall: rows x metres above its ground row beyond which an object pixel is
    not mirrored (the height of a car x the focal length: not the crowns of trees). out holds the objects'
    colours."""
    nc, height = np.uint64(contact.shape[1] - 1), view.shape[0] // width
    r0, r1, r2 = road[0], road[1], road[2]
    for r in range(extents.shape[0]):
        for p in range(extents[r, 0], extents[r, 1]):
            d = depth[p]
            if d >= FINITE:
                continue
            v = view[p]
            g = contact[v, min(np.uint64(d * STEP), nc)]
            target = 2 * g - r
            if g < 0 or (g - r) * d > tall or target <= r or target >= height:
                continue
            tp = np.uint64(np.int64(p) + (target - r) * width)
            tq, q = np.uint64(3) * tp, np.uint64(3) * p
            if abs(np.int64(src[tq]) - r0) > 1 or abs(np.int64(src[tq + 1]) - r1) > 1 or \
                    abs(np.int64(src[tq + 2]) - r2) > 1 or depth[tp] < FINITE or view[tp] != v:
                continue
            a = wetness[v, target]
            for i in range(3):
                x = np.float32(out[tq + i])
                out[tq + i] = np.uint8(x + a * (np.float32(out[q + i]) - x))


@njit(cache=True, fastmath=FAST)
def _pool_run(out, src, depth, ex, ey, bx, by, r2, rgb):
    # one row's pixels inside one disc, as arrays of their own (the compiler vectorises the loop only so)
    for i in range(depth.shape[0]):
        dx, dy = ex + i * bx, ey + i * by
        f = max(0.0, 1.0 - (dx * dx + dy * dy) / r2)
        f = f * f * (depth[i] == INF)
        for c in range(3):
            out[3 * i + c] = np.uint8(min(TOP, out[3 * i + c] + src[3 * i + c] * f * rgb[c]))


@njit(cache=True, fastmath=FAST)
def pools(out, src, depth, rows, spots, lamps, reach, rgb):
    """The street lamps' pools of light on the ground, added where no object was drawn: each a smooth disc of
    radius `reach` [m] around its centre (lamps (n, 2) [m, car frame]), lighting the renderer's colour by rgb at its
    middle. rows (n, 2): the ground's row segments (flat index of the first pixel, of the end), spots (n, 4): the
    car-frame point [m] of the first pixel's ground and its step a pixel along the row (a row's ground points lie
    on a line): only the pixels inside a disc are visited."""
    r2 = reach * reach
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
                          r2, rgb)
