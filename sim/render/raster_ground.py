"""The ground painted as sim/ground_painter.py paints it with OpenCV, compiled with numba: each flat polygon projected
to pixels in 4-bit fixed point, clipped at the near plane when it reaches behind it, and filled by OpenCV's rules for
`cv2.fillPoly(..., cv2.LINE_8, shift=4)`: every edge drawn as an 8-connected line between its rounded ends, and the
pixel rows between the edges filled from the first pixel centre at or right of the left edge to the last at or left
of the right one. The same integer steps give the same pixels.
"""
from __future__ import annotations

import numpy as np
from numba import njit

SHIFT = 4                 # sub-pixel bits of the painter's points
XY_SHIFT = 16             # OpenCV's fixed point for edges
XY_ONE = 1 << XY_SHIFT
LIMIT = 2e8               # the painter clips projected coordinates to +- this (times 16) before they are integers
# A polygon's edges are short (four pixels on average): the calls of the line and fill functions cost more than
# their loops, so numba inlines them into their callers (inline="always").


@njit(cache=True, inline="always")
def _clip_line(w, h, x1, y1, x2, y2):
    """OpenCV's clipLine on a w x h image: (inside, x1, y1, x2, y2)."""
    right, bottom = w - 1, h - 1
    c1 = (x1 < 0) + (x1 > right) * 2 + (y1 < 0) * 4 + (y1 > bottom) * 8
    c2 = (x2 < 0) + (x2 > right) * 2 + (y2 < 0) * 4 + (y2 > bottom) * 8
    if (c1 & c2) == 0 and (c1 | c2) != 0:
        if c1 & 12:
            a = 0 if c1 < 8 else bottom
            x1 += np.int64(float(a - y1) * (x2 - x1) / (y2 - y1))
            y1 = a
            c1 = (x1 < 0) + (x1 > right) * 2
        if c2 & 12:
            a = 0 if c2 < 8 else bottom
            x2 += np.int64(float(a - y2) * (x2 - x1) / (y2 - y1))
            y2 = a
            c2 = (x2 < 0) + (x2 > right) * 2
        if (c1 & c2) == 0 and (c1 | c2) != 0:
            if c1:
                a = 0 if c1 == 1 else right
                y1 += np.int64(float(a - x1) * (y2 - y1) / (x2 - x1))
                x1 = a
                c1 = 0
            if c2:
                a = 0 if c2 == 1 else right
                y2 += np.int64(float(a - x2) * (y2 - y1) / (x2 - x1))
                x2 = a
                c2 = 0
    return (c1 | c2) == 0, x1, y1, x2, y2


@njit(cache=True, inline="always")
def _line(img, x1, y1, x2, y2, r, g, b):
    """OpenCV's 8-connected line from (x1, y1) to (x2, y2), drawn left to right, clipped to the image."""
    h, w = img.shape[0], img.shape[1]
    if not (0 <= x1 < w and 0 <= x2 < w and 0 <= y1 < h and 0 <= y2 < h):
        inside, x1, y1, x2, y2 = _clip_line(w, h, x1, y1, x2, y2)
        if not inside:
            return
    dx, dy = x2 - x1, y2 - y1
    sx, sy = 1, 1
    if dx < 0:
        dx, dy = -dx, -dy
        x1, y1 = x2, y2
    if dy < 0:
        dy = -dy
        sy = -1
    vertical = dy > dx
    if vertical:
        dx, dy = dy, dx
    err = dx - (dy + dy)
    plus, minus = dx + dx, -(dy + dy)
    x, y = x1, y1
    for _ in range(dx + 1):
        img[y, x, 0] = r
        img[y, x, 1] = g
        img[y, x, 2] = b
        step = err < 0
        err += minus + (plus if step else 0)
        if vertical:   # always along y, across x when the error says so
            y += sy
            if step:
                x += sx
        else:
            x += sx
            if step:
                y += sy


@njit(cache=True, inline="always")
def fill_polygon(img, pts, r, g, b, edges):
    """cv2.fillPoly(img, [pts], (r, g, b), cv2.LINE_8, shift=4) for one polygon of int64 points (k, 2); `edges` is
    scratch space, (at least k, 4) int64."""
    h, w = img.shape[0], img.shape[1]
    k = pts.shape[0]
    delta = (1 << SHIFT) >> 1
    # a polygon whose every corner's pixel lies on one side off the image draws nothing: each edge's ends share that
    # side, so OpenCV's clipLine drops its line and leaves its ends as they are, and the rows between the edges lie
    # above or below the image, or their runs wholly left or right of it
    off = 15
    for i in range(k):
        tx = ((pts[i, 0] << (XY_SHIFT - SHIFT)) + (XY_ONE >> 1)) >> XY_SHIFT
        ty = (pts[i, 1] + delta) >> SHIFT
        off &= (tx < 0) + (tx > w - 1) * 2 + (ty < 0) * 4 + (ty > h - 1) * 8
    if off:
        return
    n = 0
    x0 = pts[k - 1, 0] << (XY_SHIFT - SHIFT)
    y0 = (pts[k - 1, 1] + delta) >> SHIFT
    for i in range(k):
        x1 = pts[i, 0] << (XY_SHIFT - SHIFT)
        y1 = (pts[i, 1] + delta) >> SHIFT
        tx0 = (x0 + (XY_ONE >> 1)) >> XY_SHIFT
        tx1 = (x1 + (XY_ONE >> 1)) >> XY_SHIFT
        ty0, ty1 = y0, y1
        _line(img, tx0, ty0, tx1, ty1, r, g, b)
        cy0, cy1 = y0, y1
        if not (0 <= tx0 < w and 0 <= tx1 < w and 0 <= ty0 < h and 0 <= ty1 < h):
            _, tx0, ty0, tx1, ty1 = _clip_line(w, h, tx0, ty0, tx1, ty1)
            if ty0 != ty1:
                cy0, cy1 = ty0, ty1
        cx0, cx1 = tx0 << XY_SHIFT, tx1 << XY_SHIFT
        if y0 != y1:
            dx = _div(cx1 - cx0, cy1 - cy0)
            if y0 < y1:
                edges[n, 0], edges[n, 1], edges[n, 2] = y0, y1, cx0 + (y0 - cy0) * dx
            else:
                edges[n, 0], edges[n, 1], edges[n, 2] = y1, y0, cx1 + (y1 - cy1) * dx
            edges[n, 3] = dx
            n += 1
        x0, y0 = x1, y1
    if n < 2:
        return
    ymin, ymax = edges[0, 0], edges[0, 1]
    for i in range(1, n):
        ymin = min(ymin, edges[i, 0])
        ymax = max(ymax, edges[i, 1])
    xs = np.empty(n, dtype=np.int64)
    for y in range(max(ymin, 0), min(ymax, h)):
        m = 0
        for i in range(n):   # the edges crossing this row, by x
            if edges[i, 0] <= y < edges[i, 1]:
                x = edges[i, 2] + (y - edges[i, 0]) * edges[i, 3]
                j = m
                while j > 0 and xs[j - 1] > x:
                    xs[j] = xs[j - 1]
                    j -= 1
                xs[j] = x
                m += 1
        for j in range(0, m - 1, 2):
            xa = (xs[j] + XY_ONE - 1) >> XY_SHIFT
            xb = xs[j + 1] >> XY_SHIFT
            if xa < w and xb >= 0:
                for x in range(max(xa, 0), min(xb, w - 1) + 1):
                    img[y, x, 0] = r
                    img[y, x, 1] = g
                    img[y, x, 2] = b


@njit(cache=True)
def _div(a, b):
    """C's integer division, which truncates towards zero."""
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b > 0) else -q


@njit(cache=True)
def _pixels(cam, n, fx, fy, w, h, out):
    """The painter's pixel coordinates (4-bit fixed point, cut towards zero) of camera-space points cam[:n]
    (right, up, forward)."""
    scale = float(1 << SHIFT)
    for i in range(n):
        u = (cam[i, 0] / cam[i, 2] * fx + w / 2) - 0.5
        v = (-cam[i, 1] / cam[i, 2] * fy + h / 2) - 0.5
        out[i, 0] = np.int64(np.int32(min(max(u * scale, -LIMIT), LIMIT)))
        out[i, 1] = np.int64(np.int32(min(max(v * scale, -LIMIT), LIMIT)))


@njit(cache=True)
def clip_near(poly, k, near, out):
    """sim/ground_painter.py's clip_near (Sutherland-Hodgman against forward >= near) of camera-space poly[:k] into
    out; returns the corners kept."""
    m = 0
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        a_in, b_in = poly[i, 2] >= near, poly[j, 2] >= near
        if a_in:
            out[m, 0], out[m, 1], out[m, 2] = poly[i, 0], poly[i, 1], poly[i, 2]
            m += 1
        if a_in != b_in:
            t = (near - poly[i, 2]) / (poly[j, 2] - poly[i, 2])
            out[m, 0] = poly[i, 0] + t * (poly[j, 0] - poly[i, 0])
            out[m, 1] = poly[i, 1] + t * (poly[j, 1] - poly[i, 1])
            out[m, 2] = near
            m += 1
    return m


@njit(cache=True)
def paint_ground(img, verts, spans, order, colours, eye, basis, near, fx, fy):
    """Paint polygons `order` (indices into spans, in painting order) into img (h, w, 3) uint8: polygon p has the
    vertices verts[spans[p, 0]:spans[p, 1]] (world, [m]) and the colour colours[spans[p, 2]]; the camera sits at
    `eye` with rows (right, up, forward) `basis`, near plane `near` [m], focal lengths fx, fy [px]."""
    h, w = img.shape[0], img.shape[1]
    most = 4
    for p in order:
        most = max(most, spans[p, 1] - spans[p, 0])
    cam = np.empty((most, 3))
    clipped = np.empty((2 * most, 3))
    pts = np.empty((2 * most, 2), dtype=np.int64)
    edges = np.empty((2 * most, 4), dtype=np.int64)
    for p in order:
        a, b, c = spans[p, 0], spans[p, 1], spans[p, 2]
        k = b - a
        lo, hi = np.inf, -np.inf
        for i in range(k):
            d0 = verts[a + i, 0] - eye[0]
            d1 = verts[a + i, 1] - eye[1]
            d2 = verts[a + i, 2] - eye[2]
            for j in range(3):
                cam[i, j] = d0 * basis[j, 0] + d1 * basis[j, 1] + d2 * basis[j, 2]
            lo = min(lo, cam[i, 2])
            hi = max(hi, cam[i, 2])
        if hi < near:
            continue
        if lo >= near:
            _pixels(cam, k, fx, fy, w, h, pts)
            m = k
        else:
            m = clip_near(cam, k, near, clipped)
            if m < 3:
                continue
            _pixels(clipped, m, fx, fy, w, h, pts)
        fill_polygon(img, pts[:m], colours[c, 0], colours[c, 1], colours[c, 2], edges)
