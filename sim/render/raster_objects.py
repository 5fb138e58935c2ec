"""Objects drawn as PyBullet's TinyRenderer draws them, compiled with numba: each body's triangles transformed in
float32 by its model, view and projection matrices, back faces culled in world space, triangles that cross the eye's
plane clipped at the near plane, every pixel whose corner lies inside or on a triangle's edge sampled (TinyRenderer
samples a pixel at its corner, not its centre), depth tested with later bodies winning ties, and lit per pixel
without shadows or specular light: int(ambient c + diffuse max(0, n.l) c) for a base colour c of whole levels
(base_colour). Drawn into an image whose rows go top down, as PyBullet returns them.
"""
from __future__ import annotations

import numpy as np
from numba import njit

DEGENERATE = 1e-2   # TinyRenderer drops a triangle whose doubled screen area is no more than this [px^2]
GAP = 1e-3          # [px] a candidate pixel this far outside a triangle's box is outside it whatever the rounding
# A corner exactly in the eye's plane (clip w = 0) divides by zero: the kernels that divide by w take IEEE's infinities,
# as TinyRenderer's C++ does (error_model="numpy"), where numba's default would raise ZeroDivisionError mid-frame.
# _raster and outside are inlined into draw_body (inline="always"): a call a triangle or block costs more than most
# small triangles' pixels. Inlined code takes its caller's error model, so draw_body's is numpy's too.


@njit(cache=True)
def _mul(m, x, y, z, w):
    """m (4, 4) float32 times the column (x, y, z, w), row by row in float32, as TinyRenderer's matrices multiply."""
    o0 = m[0, 0] * x + m[0, 1] * y + m[0, 2] * z + m[0, 3] * w
    o1 = m[1, 0] * x + m[1, 1] * y + m[1, 2] * z + m[1, 3] * w
    o2 = m[2, 0] * x + m[2, 1] * y + m[2, 2] * z + m[2, 3] * w
    o3 = m[3, 0] * x + m[3, 1] * y + m[3, 2] * z + m[3, 3] * w
    return o0, o1, o2, o3


@njit(cache=True)
def matmul(a, b):
    """a @ b for (4, 4) float32 matrices, each entry a dot product summed in order, as TinyRenderer's."""
    out = np.empty((4, 4), dtype=np.float32)
    for i in range(4):
        for j in range(4):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j] + a[i, 3] * b[3, j]
    return out


@njit(cache=True, error_model="numpy")
def _screen(clip, w, h):
    """The viewport of TinyRenderer in float32: x' = w/2 x + w/2 w, y' = h/2 y + h/2 w, each divided by w; as
    (x0, x1, x2), (y0, y1, y2)."""
    hw, hh = np.float32(w / 2.0), np.float32(h / 2.0)
    return ((hw * clip[0, 0] + hw * clip[0, 3]) / clip[0, 3], (hw * clip[1, 0] + hw * clip[1, 3]) / clip[1, 3],
            (hw * clip[2, 0] + hw * clip[2, 3]) / clip[2, 3]), \
        ((hh * clip[0, 1] + hh * clip[0, 3]) / clip[0, 3], (hh * clip[1, 1] + hh * clip[1, 3]) / clip[1, 3],
         (hh * clip[2, 1] + hh * clip[2, 3]) / clip[2, 3])


@njit(cache=True)
def _edges(sx, sy):
    """What TinyRenderer's barycentric() computes of a screen triangle once, in double precision: C-A and B-A in x
    and y, and their cross product uz."""
    ax, ay = float(sx[0]), float(sy[0])
    cax, bax, cay, bay = float(sx[2]) - ax, float(sx[1]) - ax, float(sy[2]) - ay, float(sy[1]) - ay
    return ax, ay, cax, bax, cay, bay, cax * bay - bax * cay


@njit(cache=True, error_model="numpy")
def _barycentric(e, px, py):
    """TinyRenderer's barycentric() of the pixel corner (px, py) in the triangle of _edges `e`: the cross product of
    (C-A, B-A, A-P) in x and in y."""
    ax, ay, cax, bax, cay, bay, uz = e
    apx, apy = ax - px, ay - py
    ux = bax * apy - apx * bay
    uy = apx * cay - cax * apy
    return 1.0 - (ux + uy) / uz, uy / uz, ux / uz


@njit(cache=True)
def _between(lo, hi):
    """Whether a triangle's screen box lo..hi (lo >= 0) along x or y holds no whole pixel and starts more than GAP
    past the one below it: its only candidate pixel, floor(lo), is outside the triangle by more than GAP, far more
    than the rounding of the test, so no pixel is drawn (a small far triangle's common case)."""
    first = np.floor(lo)
    return np.floor(hi) == first and lo - first > GAP


@njit(cache=True, error_model="numpy", inline="always")
def _raster(img, zbuf, clip, whole, clipped, normals, base, light, ambient, diffuse, near, far):
    """One triangle of clip-space corners clip (3, 4) into img and zbuf; `whole` is the triangle it was clipped
    from (itself when not `clipped`), whose corners carry the world normals (3, 3); base: its colour (3,)."""
    h, w = img.shape[0], img.shape[1]
    zero = np.float32(0.0)
    sx, sy = _screen(clip, w, h)
    wx, wy = _screen(whole, w, h) if clipped else (sx, sy)
    xmin = max(zero, min(sx[0], min(sx[1], sx[2])))
    xmax = min(np.float32(w - 1), max(sx[0], max(sx[1], sx[2])))
    ymin = max(zero, min(sy[0], min(sy[1], sy[2])))
    ymax = min(np.float32(h - 1), max(sy[0], max(sy[1], sy[2])))
    if xmin > xmax or ymin > ymax or _between(xmin, xmax) or _between(ymin, ymax):
        return
    # every pixel of the bounding box is TinyRenderer's candidate; a row's span of candidates that can be inside (the
    # barycentric coordinates are linear in x), widened by a pixel, is tested exactly and the rest skipped
    e = _edges(sx, sy)
    ax, ay, cax, bax, cay, bay, uz = e
    if abs(uz) <= DEGENERATE:
        return
    flat = normals[0, 0] == normals[1, 0] == normals[2, 0] and normals[0, 1] == normals[1, 1] == normals[2, 1] \
        and normals[0, 2] == normals[1, 2] == normals[2, 2]
    c0, c1, c2 = base[0], base[1], base[2]
    r = g = b = np.uint8(0)
    if flat:
        r, g, b = _shade(normals[0, 0], normals[0, 1], normals[0, 2], light, ambient, diffuse, c0, c1, c2)
    z0, z1, z2 = float(clip[0, 2]), float(clip[1, 2]), float(clip[2, 2])
    w0, w1, w2 = float(clip[0, 3]), float(clip[1, 3]), float(clip[2, 3])
    rw0, rw1, rw2 = 1.0 / w0, 1.0 / w1, 1.0 / w2   # depth = -(sum b z / w) / (sum b / w), perspective-correct
    zw0, zw1, zw2 = z0 * rw0, z1 * rw1, z2 * rw2
    sign = 1.0 if uz > 0 else -1.0
    size = abs(uz)
    # ux = bay x + (bax apy - ax bay), uy = -cay x + (ax cay - cax apy), uz - ux - uy: each of sign >= 0 inside
    slopes = (bay * sign, -cay * sign, (cay - bay) * sign)
    inverse = (1.0 / slopes[0] if slopes[0] else 0.0, 1.0 / slopes[1] if slopes[1] else 0.0,
               1.0 / slopes[2] if slopes[2] else 0.0)
    x0, x1 = int(xmin), int(np.floor(xmax))
    for py in range(int(ymin), int(np.floor(ymax)) + 1):
        apy = ay - py
        lo, hi = float(x0), float(x1)
        at0 = (bax * apy - ax * bay, ax * cay - cax * apy, uz - (bax * apy - ax * bay) - (ax * cay - cax * apy))
        for k in range(3):
            a, c = slopes[k], at0[k] * sign
            if a > 0:
                lo = max(lo, -c * inverse[k] - 1.0)
            elif a < 0:
                hi = min(hi, -c * inverse[k] + 1.0)
        for px in range(max(x0, int(np.floor(lo))), min(x1, int(np.ceil(hi))) + 1):
            # TinyRenderer's test b >= 0 for b = (1 - (ux + uy) / uz, uy / uz, ux / uz), decided by signs where
            # the quotient's rounding cannot matter: (ux + uy) / uz rounds to no more than 1 when ux + uy is at
            # most uz (in uz's sign), and to more than 1 when it is clearly more
            apx = ax - px
            ux = bax * apy - apx * bay
            uy = apx * cay - cax * apy
            if ux * sign < 0 or uy * sign < 0:
                continue
            t = (ux + uy) * sign
            if t > size and (t > size * (1.0 + 1e-12) or 1.0 - (ux + uy) / uz < 0):
                continue
            if flat:   # the depth alone, in one division: equal to TinyRenderer's but for the last bits
                u0 = uz - ux - uy
                depth = -(u0 * zw0 + uy * zw1 + ux * zw2) / (u0 * rw0 + uy * rw1 + ux * rw2)
            else:
                b0, b1, b2 = 1.0 - (ux + uy) / uz, uy / uz, ux / uz
                q0, q1, q2 = b0 / w0, b1 / w1, b2 / w2
                qs = q0 + q1 + q2
                q0, q1, q2 = q0 / qs, q1 / qs, q2 / qs
                depth = -1.0 * (z0 * q0 + z1 * q1 + z2 * q2)
            row = h - 1 - py
            if float(zbuf[row, px]) > depth:
                continue
            if not clipped and (depth < -far or depth > near):
                continue   # TinyRenderer's own near and far planes, for triangles it did not clip
            if not flat:
                if clipped:   # the normals are interpolated over the triangle the clipped one came from
                    b0, b1, b2 = _barycentric(_edges(wx, wy), float(px), float(py))
                    q0, q1, q2 = b0 / float(whole[0, 3]), b1 / float(whole[1, 3]), b2 / float(whole[2, 3])
                    qs = q0 + q1 + q2
                    q0, q1, q2 = q0 / qs, q1 / qs, q2 / qs
                f0, f1, f2 = np.float32(q0), np.float32(q1), np.float32(q2)
                nx = normals[0, 0] * f0 + normals[1, 0] * f1 + normals[2, 0] * f2
                ny = normals[0, 1] * f0 + normals[1, 1] * f1 + normals[2, 1] * f2
                nz = normals[0, 2] * f0 + normals[1, 2] * f1 + normals[2, 2] * f2
                r, g, b = _shade(nx, ny, nz, light, ambient, diffuse, c0, c1, c2)
            zbuf[row, px] = depth
            img[row, px, 0] = r
            img[row, px, 1] = g
            img[row, px, 2] = b


@njit(cache=True)
def _shade(nx, ny, nz, light, ambient, diffuse, c0, c1, c2):
    """TinyRenderer's colour for a (not yet unit) normal: int(ambient c + (diffuse max(0, n.l)) c), at most 255."""
    n = np.float32(np.sqrt(nx * nx + ny * ny + nz * nz))
    nx, ny, nz = nx / n, ny / n, nz / n
    d = max(np.float32(0.0), nx * light[0] + ny * light[1] + nz * light[2])
    k = diffuse * d
    r = min(int(ambient * c0 + k * c0), 255)
    g = min(int(ambient * c1 + k * c1), 255)
    b = min(int(ambient * c2 + k * c2), 255)
    return np.uint8(r), np.uint8(g), np.uint8(b)


MARGIN = 0.05         # [m] slack of a block's culling sphere, far more than float32's rounding of the frame's points
MARGIN_SHARE = 1e-3   # and a share of its distance from the eye


@njit(cache=True, inline="always")
def outside(spheres, k, pose, view, p00, p11):
    """Whether the bounding sphere spheres[k] (centre in the body's frame, radius [m]) of a body placed by `pose`
    (cos yaw, sin yaw, x, y) lies wholly behind the eye's plane or beyond one of the side planes of a view of
    float32 matrix `view` and projection scales p00, p11, by the margins: then none of its triangles has a pixel in
    the view (their screen boxes lie off the image) and skipping them changes nothing."""
    c, s = pose[0], pose[1]
    x, y, wz, radius = spheres[k, 0], spheres[k, 1], spheres[k, 2], spheres[k, 3]
    wx, wy = c * x - s * y + pose[2], s * x + c * y + pose[3]
    ex = float(view[0, 0]) * wx + float(view[0, 1]) * wy + float(view[0, 2]) * wz + float(view[0, 3])
    ey = float(view[1, 0]) * wx + float(view[1, 1]) * wy + float(view[1, 2]) * wz + float(view[1, 3])
    ez = float(view[2, 0]) * wx + float(view[2, 1]) * wy + float(view[2, 2]) * wz + float(view[2, 3])
    r = radius + MARGIN + MARGIN_SHARE * np.sqrt(ex * ex + ey * ey + ez * ez)
    if ez > r:
        return True   # behind the eye (clip w = -z < 0 throughout)
    # clip x - w = p00 x + z: the sphere's distance from the plane x = w, and likewise for -w, y = w and y = -w
    kx, ky = 1.0 / np.sqrt(p00 * p00 + 1.0), 1.0 / np.sqrt(p11 * p11 + 1.0)
    return (p00 * ex + ez) * kx > r or (ez - p00 * ex) * kx > r or (p11 * ey + ez) * ky > r or (ez - p11 * ey) * ky > r


@njit(cache=True, error_model="numpy")
def draw_body(img, zbuf, verts, normals, colours, painted, blocks, spheres, first, end, model, pose, paint, view,
              projection, eye, light, ambient, diffuse, still):
    """Blocks first..end of `blocks` (triangle ranges, each in a bounding sphere `spheres` (cx, cy, cz, r)) of verts
    (n, 3, 3), normals (n, 3, 3), colours (n, 3) (base colours; a triangle with `painted` true takes `paint`
    instead), placed by `model` (4, 4; `pose` its cos yaw, sin yaw, x, y in double precision) and seen through
    `view` and `projection` (4, 4) from `eye` (3,) [m], all float32; a block outside the view is skipped.
    `still`: the model is the identity (the scenery), which leaves every point and normal as it is, so they are not
    multiplied by it."""
    p00, p11 = float(projection[0, 0]), float(projection[1, 1])
    pvm = matmul(projection, matmul(view, model))
    near = projection[2, 3] / (projection[2, 2] - np.float32(1.0))   # as TinyRenderer's shader finds its planes
    far = projection[2, 3] / (projection[2, 2] + np.float32(1.0))
    clip = np.empty((3, 4), dtype=np.float32)
    nrm = np.empty((3, 3), dtype=np.float32)
    world = np.empty((3, 3), dtype=np.float32)
    fan = np.empty((6, 4), dtype=np.float32)
    tri = np.empty((3, 4), dtype=np.float32)
    one, zero = np.float32(1.0), np.float32(0.0)
    for block in range(first, end):
        if outside(spheres, block, pose, view, p00, p11):
            continue
        for t in range(blocks[block, 0], blocks[block, 1]):
            for k in range(3):   # world space first: a back face needs nothing more
                x, y, z = verts[t, k, 0], verts[t, k, 1], verts[t, k, 2]
                if still:
                    world[k, 0], world[k, 1], world[k, 2] = x, y, z
                else:
                    world[k, 0], world[k, 1], world[k, 2], _ = _mul(model, x, y, z, one)
            ax, ay, az = world[1, 0] - world[0, 0], world[1, 1] - world[0, 1], world[1, 2] - world[0, 2]
            bx, by, bz = world[2, 0] - world[0, 0], world[2, 1] - world[0, 1], world[2, 2] - world[0, 2]
            nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
            if (world[0, 0] - eye[0]) * nx + (world[0, 1] - eye[1]) * ny + (world[0, 2] - eye[2]) * nz >= zero:
                continue   # a back face
            for k in range(3):
                clip[k, 0], clip[k, 1], clip[k, 2], clip[k, 3] = _mul(pvm, verts[t, k, 0], verts[t, k, 1],
                                                                      verts[t, k, 2], one)
                if still:
                    nrm[k, 0], nrm[k, 1], nrm[k, 2] = normals[t, k, 0], normals[t, k, 1], normals[t, k, 2]
                else:
                    nrm[k, 0], nrm[k, 1], nrm[k, 2], _ = _mul(model, normals[t, k, 0], normals[t, k, 1],
                                                              normals[t, k, 2], zero)
            base = paint if painted[t] else colours[t]
            behind = (clip[0, 3] < zero) + (clip[1, 3] < zero) + (clip[2, 3] < zero)
            if behind == 3:
                continue
            if behind == 0:
                _raster(img, zbuf, clip, clip, False, nrm, base, light, ambient, diffuse, near, far)
                continue
            m = 0   # clip every edge at the near plane (z > -w), then draw the fan
            for k in range(3):
                j = (k + 1) % 3
                a_in = clip[k, 3] > zero and clip[k, 2] > -clip[k, 3]
                b_in = clip[j, 3] > zero and clip[j, 2] > -clip[j, 3]
                if not a_in and not b_in:
                    continue
                d0, d1 = clip[k, 2] + clip[k, 3], clip[j, 2] + clip[j, 3]
                # both ends of every edge kept: the fan's repeated points make empty triangles, dropped
                f = one / (d1 - d0) if not (a_in and b_in) else one
                for i in range(4):
                    new = (clip[k, i] * d1 - clip[j, i] * d0) * f
                    fan[m, i] = clip[k, i] if a_in else new
                    fan[m + 1, i] = clip[j, i] if b_in else new
                m += 2
            if m < 3:
                continue
            for i in range(1, m - 1):
                tri[0], tri[1], tri[2] = fan[0], fan[i], fan[i + 1]
                _raster(img, zbuf, tri, clip, True, nrm, base, light, ambient, diffuse, near, far)
