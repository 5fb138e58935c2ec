"""The lights a condition draws over a frame, compiled with numba (sim/render/effects.py says what each is): the
glows of cars' lights and street lamps (hidden behind what the renderer drew in front of them, reflected by a wet
road), the sun's glare and the rain's streaks; and `draw`, the whole of a frame's effects in one call.

`cams` holds a row per view of the frame (sim/render/effects.py CAMS): where its camera is, where it looks and
where its image is in the frame.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import njit

from sim.render.effect_kernels import FAST, copy, ground, objects, pools
from sim.render.kernel_cache import drop_stale

FAR = 200.0         # [m] lights and lamps farther from the host are not drawn
LIT_OBJECTS = 45.0  # [m] the street lamps light the objects near their pools nearer than this (farther: a few pixels)
POOLS_REACH = 150.0   # [m] ... and their pools are drawn on the ground nearer than this
RAIN_FALL = 23      # [px] the rain's streaks fall a frame
KERNELS = ("effect_kernels.py", "light_kernels.py")   # draw's code and the code it calls


def drop_stale_draw(folder: Path = Path(__file__).parent) -> None:
    """This file's cached code (draw holds effect_kernels.py's) is dropped when either file has changed
    (sim/render/kernel_cache.py)."""
    drop_stale(folder, KERNELS, "light_kernels.*", "effect-kernels.sha1")


drop_stale_draw()


@njit(cache=True)
def to_car(px, py, x, y, yaw):
    """A world point (px, py) [m] in the frame of a car at (x, y) with yaw [rad] (x forward, y left)."""
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = px - x, py - y
    return c * dx + s * dy, -s * dx + c * dy


@njit(cache=True)
def near_lamps(centres, x, y, yaw, within, cams):
    """The lamps' pool centres (n, 2) [m, world] within `within` [m] of a car at (x, y) with yaw [rad]: their x, y
    in its frame, then their distances along each view's axis (of cams)."""
    out = np.empty((centres.shape[0], 2 + cams.shape[0]), dtype=np.float32)
    n = 0
    for k in range(centres.shape[0]):
        lx, ly = to_car(centres[k, 0], centres[k, 1], x, y, yaw)
        if lx * lx + ly * ly < within * within:
            out[n, 0], out[n, 1] = lx, ly
            for v in range(cams.shape[0]):
                out[n, 2 + v] = (lx - cams[v, 0]) * cams[v, 9] + (ly - cams[v, 1]) * cams[v, 10] - cams[v, 2] * \
                    cams[v, 11]
            n += 1
    return out[:n]


@njit(cache=True)
def project(cams, v, px, py, pz):
    """A car-frame point [m] in view v of cams (views, 22: eye (3), right, up, forward rows (9), fx, fy [px], rect
    (top, left, height, width), mirrored, near [m], hfov [rad], reach [m]): frame column, row [px] and distance
    along the view's axis [m]; distance < 0: behind the camera."""
    qx, qy, qz = px - cams[v, 0], py - cams[v, 1], pz - cams[v, 2]
    a = qx * cams[v, 3] + qy * cams[v, 4] + qz * cams[v, 5]
    b = qx * cams[v, 6] + qy * cams[v, 7] + qz * cams[v, 8]
    d = qx * cams[v, 9] + qy * cams[v, 10] + qz * cams[v, 11]
    if d <= cams[v, 19]:
        return 0.0, 0.0, -1.0
    top, left, vh, vw = cams[v, 14], cams[v, 15], cams[v, 16], cams[v, 17]
    x = a / d * cams[v, 12] + vw / 2
    col = left + (vw - x if cams[v, 18] else x)
    return col, top + vh / 2 - b / d * cams[v, 13], d


@njit(cache=True, fastmath=FAST)
def glow(out, depth, view, cams, v, px, py, pz, radius, rgb, strength, fog, streak, across):
    """A light at a car-frame point [m] added to view v of out (h, w, 3) as a glow of `radius` [m] (at least 0.6 px),
    colour rgb (0-255) at full strength, hidden where the depth shows an object more than a metre in front of it, dimmed
    by the fog (density per metre, 0: none); streak > 0: a wet road's reflection that many radii below. The glow is s
    exp(-q) for q = dx^2 + dy^2 < 9 (in radii); a pixel gains its integer part only, so the glow stops where s exp(-q) x
    the brightest channel falls under a level (its square's rows, and in them each pixel left unread), and exp(-q) is
    exp(-dx^2) exp(-dy^2): one exp a row and one a column, those of the columns kept in `across` (room for a row of the
    frame: one array for every glow of a frame, not one each)."""
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
    flat, where, width = out.reshape(-1), view.reshape(-1), np.uint64(view.shape[1])
    lit = 0.999 / max(rgb[0], rgb[1], rgb[2])   # a pixel gains less than a level where g is under this: none
    for r in range(max(top, ir - reach), min(top + vh, ir + reach + below + 1)):
        dy = (r + 0.5 - row) / rad
        if dy > 0.0 and streak > 0.0:
            dy = dy / (1.0 + streak)
        if dy * dy >= q_max:
            continue
        up = s * math.exp(-dy * dy)
        first = np.uint64(r) * width + np.uint64(c0)
        for j in range(np.uint64(c1 - c0)):   # unsigned indices: numba tests a signed one for wrapping around
            g = up * across[j]
            if g >= lit and where[first + j] == v:
                q = np.uint64(3) * (first + j)
                for i in range(np.uint64(3)):
                    flat[q + i] = np.uint8(min(255.0, flat[q + i] + g * rgb[i]))


@njit(cache=True, fastmath=FAST)
def car_lights(out, depth, view, cams, x, y, yaw, car_x, car_y, car_yaw, car_models, tails, heads, tail_rgb,
               head_rgb, strength, fog, streak):
    """The tail lights of the cars seen from behind and the headlights of those seen from ahead: tails, heads
    (models, 2, 3) [m] each model's pair in its car's frame."""
    across = np.empty(out.shape[1])
    for k in range(len(car_x)):
        ax, ay = to_car(car_x[k], car_y[k], x, y, yaw)
        if ax * ax + ay * ay > FAR * FAR:
            continue
        c, s = math.cos(car_yaw[k]), math.sin(car_yaw[k])
        behind = (x - car_x[k]) * c + (y - car_y[k]) * s < 0.0
        pair, rgb, radius = (tails, tail_rgb, 0.16) if behind else (heads, head_rgb, 0.2)
        m = car_models[k]
        for i in range(2):
            lx, ly = to_car(car_x[k] + c * pair[m, i, 0] - s * pair[m, i, 1],
                            car_y[k] + s * pair[m, i, 0] + c * pair[m, i, 1], x, y, yaw)
            for v in range(cams.shape[0]):
                glow(out, depth, view, cams, v, lx, ly, pair[m, i, 2], radius, rgb, strength, fog, streak, across)


@njit(cache=True, fastmath=FAST)
def lamp_heads(out, depth, view, cams, x, y, yaw, heads, height, rgb):
    """The street lamps themselves: heads (n, 2) world [m], `height` [m] up."""
    across = np.empty(out.shape[1])
    for k in range(heads.shape[0]):
        lx, ly = to_car(heads[k, 0], heads[k, 1], x, y, yaw)
        if lx * lx + ly * ly < FAR * FAR:
            for v in range(cams.shape[0]):
                glow(out, depth, view, cams, v, lx, ly, height, 0.35, rgb, 0.9, 0.0, 0.0, across)


@njit(cache=True, fastmath=FAST)
def glare(out, view, cams, sun, sprite):
    """The sun's glare and disc: sprite (2 k + 1, 2 k + 1) of how far each pixel around the sun goes to white, in
    the front view's pixels, added where the sun (sun: unit vector, car frame) is in a view."""
    k = sprite.shape[0] // 2
    for v in range(cams.shape[0]):
        col, row, d = project(cams, v, cams[v, 0] + sun[0] * 1e3, cams[v, 1] + sun[1] * 1e3,
                              cams[v, 2] + sun[2] * 1e3)
        if d <= 0.0:
            continue
        ic, ir = int(math.floor(col)), int(math.floor(row))
        top, left, vh, vw = int(cams[v, 14]), int(cams[v, 15]), int(cams[v, 16]), int(cams[v, 17])
        for r in range(max(top, ir - k), min(top + vh, ir + k + 1)):
            for c in range(max(left, ic - k), min(left + vw, ic + k + 1)):
                if view[r, c] == v:
                    g = sprite[r - ir + k, c - ic + k]
                    out[r, c, 0] = np.uint8(out[r, c, 0] + g * (255.0 - out[r, c, 0]))
                    out[r, c, 1] = np.uint8(out[r, c, 1] + g * (250.0 - out[r, c, 1]))
                    out[r, c, 2] = np.uint8(out[r, c, 2] + g * (230.0 - out[r, c, 2]))


@njit(cache=True, fastmath=FAST)
def streaks(out, view, at, alpha, levels, spans, period, offset, rgb, bordered):
    """Rain streaks: pixels (at: flat index in the texture, alpha: a byte, levels[alpha] its weight 0-1; sorted by
    row) of a texture `period` rows tall, shown `offset` rows further down each frame (wrapping), blended towards rgb
    over every view (bordered: the frame has pixels of no view, the insets' borders, left as they are); spans (n, 2):
    the ranges of the pixels that show this frame."""
    flat, where = out.reshape(-1), view.reshape(-1)
    size, shift = np.uint64(period * view.shape[1]), np.uint64(offset * view.shape[1])
    c0, c1, c2 = rgb[0], rgb[1], rgb[2]
    for k in range(spans.shape[0]):
        for i in range(np.uint64(spans[k, 0]), np.uint64(spans[k, 1])):
            p = np.uint64(at[i]) + shift
            if p >= size:
                p -= size
            if bordered and where[p] < 0:
                continue
            a, q = levels[alpha[i]], np.uint64(3) * p
            flat[q] = np.uint8(flat[q] + a * (c0 - flat[q]))
            flat[q + 1] = np.uint8(flat[q + 1] + a * (c1 - flat[q + 1]))
            flat[q + 2] = np.uint8(flat[q + 2] + a * (c2 - flat[q + 2]))


@njit(cache=True, fastmath=FAST)
def draw(out, src, depth, x, y, yaw, frame, cars, view, cams, shades, ground_, objects_, lamps, lights, sun, rain):
    """The whole of a frame's effects (sim/render/effects.py Effects.apply) in one call, from src (h, w, 3) into out
    (a copy of src where no depth is given: numpy copies faster); depth (h, w) [m] ((0, 0): none read back); the
    host at (x, y) [m] with yaw [rad], `frame` its frame's number (the rain falls); cars: (x, y, yaw, model) arrays
    of the other cars; view (h, w) and cams (sim/render/conditions.py Geometry); shades: whether the fog, the dark
    and the wet road are drawn; the tables of each effect, grouped: ground_ (spans, fog, lit, gain, dark, fog_rgb),
    objects_ (reach, cone, fall, fog, lamp_rgb, reach of a lamp's pool, contact, wetness, road, tall, the rows'
    views, the beams' reach, the distances a row's pixels are mirrored within, the rows' runs of one view, whether
    the frame has one view), lamps (pool centres, heads, height, glow, the ground's rows, their spots; no centres:
    none), lights (tails, heads, tail_rgb, head_rgb, strength, fog, streak), sun (direction, sprite; (0, 0): none),
    rain (flat indices, alphas, the rows' starts, rgb, the alphas' weights, whether the frame has borders)."""
    flat, deep, bytes_ = out.reshape(-1), depth.reshape(-1), src.reshape(-1)
    if depth.shape[0] and shades:
        spans, fog, lit, gain, dark, fog_rgb = ground_
        ground(flat, bytes_, spans, fog, lit, gain, dark, fog_rgb)
        reach, cone, fall, fog_table, lamp_rgb, lamp_reach, contact, wetness, road, tall, row_view, beam, near, \
            segments, one_view = objects_
        objects(flat, bytes_, deep, view.reshape(-1), view.shape[1], reach, cams, cone, fall, fog_table, dark, gain,
                fog_rgb, near_lamps(lamps[0], x, y, yaw, LIT_OBJECTS, cams), lamp_reach, lamp_rgb,
                (contact, wetness, road, tall, near, one_view), row_view, segments, beam)
    elif depth.shape[0]:
        copy(flat, bytes_, np.uint64(0), np.uint64(flat.shape[0]))
    if depth.shape[0]:
        _lamps(flat, bytes_, deep, out, depth, x, y, yaw, view, cams, objects_[4], objects_[5], lamps)
        if cars[0].shape[0] and lights[4] > 0.0:
            tails, heads, tail_rgb, head_rgb, strength, fog_density, streak = lights
            car_lights(out, depth, view, cams, x, y, yaw, cars[0], cars[1], cars[2], cars[3], tails, heads, tail_rgb,
                       head_rgb, strength, fog_density, streak)
    if sun[1].shape[0]:
        ch, sh, s = math.cos(yaw), math.sin(yaw), sun[0]
        glare(out, view, cams, np.array([ch * s[0] + sh * s[1], -sh * s[0] + ch * s[1], s[2]]), sun[1])
    if rain[0].shape[0]:
        _rain(out, view, frame, rain)


@njit(cache=True, fastmath=FAST)
def _lamps(flat, src, deep, out, depth, x, y, yaw, view, cams, lamp_rgb, lamp_reach, lamps):
    """The street lamps' pools on the ground and the lamps themselves."""
    centres, heads, height, glow_rgb, rows, spots = lamps
    if centres.shape[0]:
        pools(flat, src, deep, rows, spots, near_lamps(centres, x, y, yaw, POOLS_REACH, cams), lamp_reach, lamp_rgb)
        lamp_heads(out, depth, view, cams, x, y, yaw, heads, height, glow_rgb)


@njit(cache=True)
def _rain(out, view, frame, rain):
    """The rain's streaks of frame number `frame`: the texture's rows from the one shown at the top, wrapping."""
    texture_at, alpha, at, rgb, levels, bordered = rain
    period = at.shape[0] - 1
    offset = (frame * RAIN_FALL) % period
    first = (period - offset) % period   # the texture's row shown at the top, then h more
    last = first + out.shape[0]
    spans = np.empty((2, 2), dtype=np.int64)
    spans[0, 0], spans[0, 1] = at[first], at[min(last, period)]
    spans[1, 0], spans[1, 1] = at[0], at[max(last - period, 0)]
    streaks(out, view, texture_at, alpha, levels, spans, period, offset, rgb, bordered)
