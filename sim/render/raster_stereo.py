"""A parallel stereo rig's layers painted as sim/sidewalk/stereo.py's OpenCV painters paint them, compiled with numba:
the backdrop, the ground's flat polygons (cv2.fillPoly's rules, sim/render/raster_ground.py) and the objects' convex
faces (cv2.fillConvexPoly's, here), both eyes in one call. The painters' numpy code moves the geometry into the rig's
centre camera (a matrix product whose rounding is the BLAS library's, so it stays theirs); these kernels take it from
there with the painters' own arithmetic: the culling, the order, the near-plane clip, the fixed-point pixels, the
filled pixels. The images are the painters' byte for byte.

`fill_convex` follows OpenCV's FillConvexPoly for LINE_8 and 4-bit fixed-point points: every edge drawn by Line2
(16-bit fixed point, clipped to the image), then two edges walked down from the top vertex, each row filled between
their rounded x. Rows above the image are skipped in one step where OpenCV walks them (the same x at the first row
drawn): a face reaching far above the frame costs no more than one inside it.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from sim.render.raster import drop_stale_kernels
from sim.render.raster_ground import _clip_line, _div, clip_near, fill_polygon

SHIFT = 4                 # sub-pixel bits of the painters' points
XY_SHIFT = 16             # OpenCV's fixed point for edges
XY_ONE = 1 << XY_SHIFT
LIMIT = 2e8               # the painters clip projected coordinates to +- this (times 16) before they are integers

drop_stale_kernels()      # this file's kernels call raster_ground.py's: numba's cache of them goes when it changes


@njit(cache=True)
def _put(img, depth, x, y, r, g, b, z):
    img[y, x, 0] = r
    img[y, x, 1] = g
    img[y, x, 2] = b
    if depth is not None:
        depth[y, x] = z


@njit(cache=True)
def _line2(img, depth, x1, y1, x2, y2, r, g, b, z):
    """OpenCV's Line2: an 8-connected line between points in 16-bit fixed point, clipped to the image."""
    h, w = img.shape[0], img.shape[1]
    inside, x1, y1, x2, y2 = _clip_line(w << XY_SHIFT, h << XY_SHIFT, x1, y1, x2, y2)
    if not inside:
        return
    dx, dy = x2 - x1, y2 - y1
    ax, ay = abs(dx), abs(dy)
    x_step, y_step = XY_ONE, XY_ONE
    if ax > ay:
        if dx < 0:
            x1, x2, y1, y2, dy = x2, x1, y2, y1, -dy
        y_step = _div(dy << XY_SHIFT, ax | 1)
        count = (x2 - x1) >> XY_SHIFT
    else:
        if dy < 0:
            x1, x2, y1, y2, dx = x2, x1, y2, y1, -dx
        x_step = _div(dx << XY_SHIFT, ay | 1)
        count = (y2 - y1) >> XY_SHIFT
    x1 += XY_ONE >> 1
    y1 += XY_ONE >> 1
    ex, ey = (x2 + (XY_ONE >> 1)) >> XY_SHIFT, (y2 + (XY_ONE >> 1)) >> XY_SHIFT
    if 0 <= ex < w and 0 <= ey < h:
        _put(img, depth, ex, ey, r, g, b, z)
    if ax > ay:
        x1 >>= XY_SHIFT
        for _ in range(count + 1):
            py = y1 >> XY_SHIFT
            if 0 <= x1 < w and 0 <= py < h:
                _put(img, depth, x1, py, r, g, b, z)
            x1 += 1
            y1 += y_step
    else:
        y1 >>= XY_SHIFT
        for _ in range(count + 1):
            px = x1 >> XY_SHIFT
            if 0 <= px < w and 0 <= y1 < h:
                _put(img, depth, px, y1, r, g, b, z)
            x1 += x_step
            y1 += 1


@njit(cache=True)
def _line2_in(img, depth, x1, y1, x2, y2, r, g, b, z):
    """_line2 of a line whose pixels all lie in the image: nothing to clip or test."""
    dx, dy = x2 - x1, y2 - y1
    ax, ay = abs(dx), abs(dy)
    if ax > ay:
        if dx < 0:
            x1, x2, y1, y2, dy = x2, x1, y2, y1, -dy
        y_step = _div(dy << XY_SHIFT, ax | 1)
        y1 += XY_ONE >> 1
        x = (x1 + (XY_ONE >> 1)) >> XY_SHIFT
        _put(img, depth, (x2 + (XY_ONE >> 1)) >> XY_SHIFT, (y2 + (XY_ONE >> 1)) >> XY_SHIFT, r, g, b, z)
        for _ in range(((x2 - x1) >> XY_SHIFT) + 1):
            _put(img, depth, x, y1 >> XY_SHIFT, r, g, b, z)
            x += 1
            y1 += y_step
    else:
        if dy < 0:
            x1, x2, y1, y2, dx = x2, x1, y2, y1, -dx
        x_step = _div(dx << XY_SHIFT, ay | 1)
        x1 += XY_ONE >> 1
        y = (y1 + (XY_ONE >> 1)) >> XY_SHIFT
        _put(img, depth, (x2 + (XY_ONE >> 1)) >> XY_SHIFT, (y2 + (XY_ONE >> 1)) >> XY_SHIFT, r, g, b, z)
        for _ in range(((y2 - y1) >> XY_SHIFT) + 1):
            _put(img, depth, x1 >> XY_SHIFT, y, r, g, b, z)
            x1 += x_step
            y += 1


@njit(cache=True)
def _span(img, depth, y, xa, xb, r, g, b, z):
    """Row y from column xa to xb (both included)."""
    row = img[y]
    for x in range(xa, xb + 1):
        row[x, 0] = r
        row[x, 1] = g
        row[x, 2] = b
    if depth is not None:
        drow = depth[y]
        for x in range(xa, xb + 1):
            drow[x] = z


@njit(cache=True)
def _next_edge(v, n, y, edges, idx0, di):
    """FillConvexPoly's walk along one side from vertex idx0 to the first vertex below row y: (edges left, its
    index, its row, the start's x in 16-bit fixed point, the x step a row); the index -1 when the sides ran out."""
    delta = (1 << SHIFT) >> 1
    idx = idx0 + di
    if idx >= n:
        idx -= n
    while True:
        more = edges > 0
        edges -= 1
        if not more:
            return edges, -1, 0, 0, 0
        ty = (v[idx, 1] + delta) >> SHIFT
        if ty > y:
            xs = v[idx0, 0] << (XY_SHIFT - SHIFT)
            xe = v[idx, 0] << (XY_SHIFT - SHIFT)
            return edges, idx, ty, xs, _div((xe - xs) * 2 + (ty - y), 2 * (ty - y))
        idx0 = idx
        idx += di
        if idx >= n:
            idx -= n


@njit(cache=True)
def _outline(img, depth, v, n, r, g, b, z):
    """FillConvexPoly's edges, each drawn by Line2; returns the points' bounds in pixels and the topmost point. An
    edge of no length (a triangle's repeated corner) is left out: its one pixel is an end of the edges beside it,
    which draw both their ends, unless every point is the same."""
    h, w = img.shape[0], img.shape[1]
    up = XY_SHIFT - SHIFT
    xmin, xmax, ymin, ymax, imin = v[0, 0], v[0, 0], v[0, 1], v[0, 1], 0
    for i in range(n):
        if v[i, 1] < ymin:
            ymin, imin = v[i, 1], i
        ymax, xmax, xmin = max(ymax, v[i, 1]), max(xmax, v[i, 0]), min(xmin, v[i, 0])
    point = xmin == xmax and ymin == ymax
    # every point's pixel in the image: no line needs clipping or a test a pixel
    inside = xmin >= 0 and ymin >= 0 and xmax < (w << SHIFT) - 8 and ymax < (h << SHIFT) - 8
    p0x, p0y = v[n - 1, 0] << up, v[n - 1, 1] << up
    for i in range(n):
        px, py = v[i, 0] << up, v[i, 1] << up
        if point or px != p0x or py != p0y:
            if inside:
                _line2_in(img, depth, p0x, p0y, px, py, r, g, b, z)
            else:
                _line2(img, depth, p0x, p0y, px, py, r, g, b, z)
        p0x, p0y = px, py
    delta = (1 << SHIFT) >> 1
    return (xmin + delta) >> SHIFT, (xmax + delta) >> SHIFT, (ymin + delta) >> SHIFT, (ymax + delta) >> SHIFT, imin


@njit(cache=True)
def fill_convex(img, depth, v, n, r, g, b, z):
    """cv2.fillConvexPoly(img, v[:n], (r, g, b), cv2.LINE_8, shift=4) for int64 points v (at least n, 2); `depth`
    (h, w) float32 gets z on the same pixels (cv2.fillConvexPoly(depth, v[:n], z, ...)), or nothing if None (a
    kernel compiled apart, without the tests)."""
    h, w = img.shape[0], img.shape[1]
    xmin, xmax, ymin, ymax, imin = _outline(img, depth, v, n, r, g, b, z)
    if n < 3 or xmax < 0 or ymax < 0 or xmin >= w or ymin >= h:
        return
    ymax = min(ymax, h - 1)
    # the two sides walked down from the top: vertex index, row where the side turns, x and its step a row
    i0, ye0, x0, dx0 = imin, ymin, -XY_ONE, 0
    i1, ye1, x1, dx1 = imin, ymin, -XY_ONE, 0
    edges = n
    y = ymin
    half = XY_ONE >> 1
    while True:
        if y >= ye0:
            edges, k, ty, xs, step = _next_edge(v, n, y, edges, i0, 1)
            if k >= 0:
                i0, ye0, x0, dx0 = k, ty, xs, step
        if y >= ye1:
            edges, k, ty, xs, step = _next_edge(v, n, y, edges, i1, n - 1)
            if k >= 0:
                i1, ye1, x1, dx1 = k, ty, xs, step
        if edges < 0:
            return
        rows = 1
        if y >= 0:
            xa, xb = (x1 + half) >> XY_SHIFT, (x0 + half) >> XY_SHIFT
            if x0 <= x1:
                xa, xb = (x0 + half) >> XY_SHIFT, (x1 + half) >> XY_SHIFT
            if xb >= 0 and xa < w:
                _span(img, depth, y, max(xa, 0), min(xb, w - 1), r, g, b, z)
        else:   # above the image: straight on to the first row where a side turns or the image begins
            rows = max(1, min(ye0, ye1, 0) - y)
        x0 += dx0 * rows
        x1 += dx1 * rows
        y += rows
        if y > ymax:
            return


@njit(cache=True)
def draw_backdrop(frame, sky, pano, top, columns):
    """frame = sky, its rows top.. from the panorama's `columns` (frame = sky.copy(); frame[top:bottom] = pano[:,
    columns]); all (h, w, 3) uint8, C-contiguous."""
    h, w = frame.shape[0], frame.shape[1]
    out, src = frame.reshape(h, 3 * w), sky.reshape(h, 3 * w)
    for y in range(h):
        if top <= y < top + pano.shape[0]:
            for x in range(w):
                c = columns[x]
                out[y, 3 * x], out[y, 3 * x + 1], out[y, 3 * x + 2] = pano[y - top, c, 0], pano[y - top, c, 1], \
                    pano[y - top, c, 2]
        else:
            for i in range(3 * w):
                out[y, i] = src[y, i]


@njit(cache=True)
def _ground_pixels(x, y, z, fx, fy, w, h):
    """sim/ground_painter.py's _to_pixels of one camera-space point: 4-bit fixed point, cut towards zero."""
    u = (x / z * fx + w / 2 - 0.5) * float(1 << SHIFT)
    v = (-y / z * fy + h / 2 - 0.5) * float(1 << SHIFT)
    return np.int64(np.int32(min(max(u, -LIMIT), LIMIT))), np.int64(np.int32(min(max(v, -LIMIT), LIMIT)))


@njit(cache=True)
def _ground_inside(cam, table, near_polys, detail, near, half, tx, ty):
    """sim/sidewalk/ground.py's culling: per polygon, whether it reaches into one eye's frustum (and is painted at
    its chunk's distance), and its nearest depth."""
    inside = np.zeros(table.shape[0], dtype=np.bool_)
    lo = np.empty(table.shape[0])
    for k in range(table.shape[0]):
        zlo, zhi, m1, m2, m3, m4 = np.inf, -np.inf, np.inf, np.inf, np.inf, np.inf
        for i in range(table[k, 1], table[k, 2]):
            x, y, z = cam[i, 0], cam[i, 1], cam[i, 2]
            zlo, zhi = min(zlo, z), max(zhi, z)
            m1, m2 = min(m1, x - half - z * tx), min(m2, -x - half - z * tx)
            m3, m4 = min(m3, y - z * ty), min(m4, -y - z * ty)
        lo[k] = zlo
        seen = zhi > near and m1 < 0 and m2 < 0 and m3 < 0 and m4 < 0
        inside[k] = seen and (near_polys[k] or not detail[table[k, 0]])
    return inside, lo


@njit(cache=True)
def paint_ground_pair(left, right, cam, table, near_polys, detail, colours, near, half, tx, ty, fx, fy):
    """sim/sidewalk/ground.py's paint_pair from the vertices in the rig's centre camera `cam` (n, 3): polygon k is
    cam[table[k, 1]:table[k, 2]] in colour colours[table[k, 0]] (its rank: painted in rank order, stably); near_polys
    per polygon and detail per rank say which details to paint. Returns the polygons painted."""
    h, w = left.shape[0], left.shape[1]
    inside, lo = _ground_inside(cam, table, near_polys, detail, near, half, tx, ty)
    most = 4
    for k in range(table.shape[0]):
        most = max(most, table[k, 2] - table[k, 1])
    clipped = np.empty((2 * most, 3))
    pl = np.empty((2 * most, 2), dtype=np.int64)
    pr = np.empty((2 * most, 2), dtype=np.int64)
    edges = np.empty((2 * most, 4), dtype=np.int64)
    painted = 0
    for rank in range(colours.shape[0]):
        r, g, b = colours[rank, 0], colours[rank, 1], colours[rank, 2]
        for k in range(table.shape[0]):
            if not inside[k] or table[k, 0] != rank:
                continue
            a = table[k, 1]
            poly, m = cam[a:table[k, 2]], table[k, 2] - a
            if lo[k] < near:
                m = clip_near(poly, m, near, clipped)
                if m < 3:
                    continue
                poly = clipped
            for i in range(m):
                pl[i, 0], pl[i, 1] = _ground_pixels(poly[i, 0] + half, poly[i, 1], poly[i, 2], fx, fy, w, h)
                pr[i, 0], pr[i, 1] = _ground_pixels(poly[i, 0] - half, poly[i, 1], poly[i, 2], fx, fy, w, h)
            fill_polygon(left, pl[:m], r, g, b, edges)
            fill_polygon(right, pr[:m], r, g, b, edges)
            painted += 1
    return painted


@njit(cache=True)
def _object_pixels(x, y, z, fx, fy, cx, cy):
    """sim/sidewalk/painter.py's _pixels of one camera-space point."""
    u = (x / z * fx + cx) * float(1 << SHIFT)
    v = (-y / z * fy + cy) * float(1 << SHIFT)
    return np.int64(np.int32(min(max(u, -LIMIT), LIMIT))), np.int64(np.int32(min(max(v, -LIMIT), LIMIT)))


@njit(cache=True)
def _inside(face, near, half, tx, ty):
    """sim/sidewalk/painter.py's frustum test of a face's corners (4, 3) in the centre camera: not wholly behind the
    near plane nor wholly outside one side, top or bottom of both eyes' view."""
    zhi, m1, m2, m3, m4 = -np.inf, np.inf, np.inf, np.inf, np.inf
    for j in range(4):
        x, y, z = face[j, 0], face[j, 1], face[j, 2]
        zhi = max(zhi, z)
        m1, m2 = min(m1, x - half - z * tx), min(m2, -x - half - z * tx)
        m3, m4 = min(m3, y - z * ty), min(m4, -y - z * ty)
    return zhi > near and m1 < 0 and m2 < 0 and m3 < 0 and m4 < 0


@njit(cache=True)
def _paint_eye(frame, depth, sign, cam, kept, order, facing, across, colours, zmean, view):
    """sim/sidewalk/painter.py's _paint_eye: of the faces `order` (those in view), those that face the eye at sign *
    half along x of the centre camera, each clipped at the near plane where it reaches behind it, filled; returns
    how many face it. view: (near, half, tx, ty, fx, fy, cx, cy)."""
    near, half, tx, ty, fx, fy, cx, cy = view
    corners = np.empty((4, 3))
    clipped = np.empty((8, 3))
    pts = np.empty((8, 2), dtype=np.int64)
    shift = sign * half
    n = 0
    for k in order:
        f = kept[k]
        if not facing[f] - sign * across[f] > 0:
            continue
        n += 1
        whole = True
        for j in range(4):
            corners[j, 0], corners[j, 1], corners[j, 2] = cam[k, j, 0] + shift, cam[k, j, 1], cam[k, j, 2]
            whole = whole and cam[k, j, 2] >= near
        poly, m = corners, 4
        if not whole:
            m = clip_near(corners, 4, near, clipped)
            if m < 3:
                continue
            poly = clipped
        for i in range(m):
            pts[i, 0], pts[i, 1] = _object_pixels(poly[i, 0], poly[i, 1], poly[i, 2], fx, fy, cx, cy)
        z = 0.0
        if zmean is not None:
            z = zmean[k]
        fill_convex(frame, depth, pts, m, colours[f, 0], colours[f, 1], colours[f, 2], z)
    return n


@njit(cache=True)
def paint_objects_pair(left, right, depth_left, depth_right, cam, kept, distance, facing, across, colours, zmean,
                       view):
    """Both eyes of sim/sidewalk/painter.py's paint_pair from the corners (F, 4, 3) in the centre camera `cam` of the
    faces `kept` (indices into facing, across, colours and distance) that face one eye or the other, painted far
    first (by `distance`, their piece's from the eye; stably), those outside the view skipped: `facing` how much each
    faces the centre eye, `across` how that changes at either eye, `zmean` the depth each leaves in the depth images
    (None: none); `view` (near, half baseline, tan of the half fields of view x and y, focal lengths x and y, centre
    x and y). Returns the faces the left eye sees."""
    key = np.empty(kept.shape[0])
    for k in range(kept.shape[0]):
        key[k] = -distance[kept[k]]
    order = np.argsort(key, kind="mergesort")
    near, half, tx, ty = view[0], view[1], view[2], view[3]
    seen = np.empty(order.shape[0], dtype=np.bool_)
    for k in range(order.shape[0]):
        seen[k] = _inside(cam[order[k]], near, half, tx, ty)
    order = order[seen]
    n = _paint_eye(left, depth_left, 1.0, cam, kept, order, facing, across, colours, zmean, view)
    _paint_eye(right, depth_right, -1.0, cam, kept, order, facing, across, colours, zmean, view)
    return n


@njit(cache=True)
def select_faces(pc, dist, radius, piece_chunk, chunk_visible, start, level, limits):
    """sim/sidewalk/painter.py's _static_faces from the pieces' centres in the centre camera `pc` and their distances:
    the faces (indices, piece by piece) of the pieces in a visible chunk, within reach, big enough and inside the
    frustum of an eye, at their level of detail. limits: (near, half baseline, tan of the half fields of view x and
    y with a pixel to spare, the focal length y, reach, the frustum's slack per metre of radius x and y, the fewest
    pixels, the detail's distance)."""
    near, half, tx, ty, fy, reach, sx, sy, fewest, lod = limits
    out = np.empty(start[-1], dtype=np.int64)
    n = 0
    for p in range(radius.shape[0]):
        r, d = radius[p], dist[p]
        if not (chunk_visible[piece_chunk[p]] and d < reach and r * fy > fewest * d):
            continue
        x, y, z = pc[p, 0], pc[p, 1], pc[p, 2]
        if not (z + r > near and abs(x) - half - z * tx < r * sx and abs(y) - z * ty < r * sy):
            continue
        close = d < lod
        for f in range(start[p], start[p + 1]):
            if level[f] == 0 or (level[f] == 1 and close) or (level[f] == 2 and not close):
                out[n] = f
                n += 1
    return out[:n]
