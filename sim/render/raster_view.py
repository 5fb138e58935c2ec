"""One camera's view drawn by the compiled rasteriser in a single call: the ground of the chunks in view in the
painter's order (sim/render/raster_ground.py), then their objects and the cars (sim/render/raster_objects.py) in the
order PyBullet's bodies were made, later ones winning ties."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.render.raster_ground import paint_ground
from sim.render.raster_objects import draw_body


@njit(cache=True)
def car_model(x, y, yaw):
    """A car's placement as PyBullet makes it from the position (x, y, 0) and the quaternion of a turn by yaw about
    z (sin and cos of yaw / 2, as sim/highway/bullet_scene.py passes them), in double precision, then float32."""
    qz, qw = math.sin(yaw / 2), math.cos(yaw / 2)
    s = 2.0 / (qz * qz + qw * qw)
    zz, wz = qz * qz * s, qw * qz * s
    m = np.zeros((4, 4), dtype=np.float32)
    m[0, 0] = m[1, 1] = 1.0 - zz
    m[0, 1], m[1, 0] = -wz, wz
    m[0, 3], m[1, 3] = x, y
    m[2, 2] = m[3, 3] = 1.0
    return m


@njit(cache=True)
def draw_view(img, chunks, ground, spans, by_rank, colours, eye, basis, near, fx, fy,
              verts, normals, bases, painted, firsts, ends, n_chunks, view, projection,
              car_x, car_y, car_yaw, car_models, car_paints, light, ambient, diffuse):
    """Into img (h, w, 3) uint8, its backdrop: the ground of the chunks `chunks` (bool), polygon p of chunk c and
    rank r listed in by_rank[r, c] (first, end) of `spans` (paint_ground), then their objects (body c: triangles
    firsts[c]..ends[c]) and the cars (body n_chunks + model, paint car_paints (k, 3)), seen through `view` and
    `projection` (float32) from `eye` (float64, with `basis`)."""
    order = np.empty(len(spans), dtype=np.int64)
    n = 0
    for r in range(by_rank.shape[0]):
        for c in range(by_rank.shape[1]):
            if chunks[c]:
                for p in range(by_rank[r, c, 0], by_rank[r, c, 1]):
                    order[n] = p
                    n += 1
    if n:
        paint_ground(img, ground, spans, order[:n], colours, eye, basis, near, fx, fy)
    zbuf = np.full(img.shape[:2], -np.inf, dtype=np.float32)
    eye32 = eye.astype(np.float32)
    identity = np.eye(4, dtype=np.float32)
    none = np.zeros(3, dtype=np.float32)
    for c in range(n_chunks):
        if chunks[c] and ends[c] > firsts[c]:
            draw_body(img, zbuf, verts, normals, bases, painted, firsts[c], ends[c], identity, none, view,
                      projection, eye32, light, ambient, diffuse, True)
    for k in range(len(car_x)):
        b = n_chunks + car_models[k]
        draw_body(img, zbuf, verts, normals, bases, painted, firsts[b], ends[b], car_model(car_x[k], car_y[k],
                  car_yaw[k]), car_paints[k], view, projection, eye32, light, ambient, diffuse, False)
