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
def camera_basis(x, y, yaw, forward, left, height, pitch_deg):
    """sim/camera.py CameraConfig.basis, step for step: the eye [m] of a camera `forward` ahead of a car at (x, y)
    with yaw [rad], `left` of its axis and `height` up, looking pitch_deg down, and its (right, up, forward) rows."""
    c, s = math.cos(yaw), math.sin(yaw)
    eye = np.array([x + forward * c, y + forward * s, height])
    if left:
        eye[0] += -left * s
        eye[1] += left * c
    p = pitch_deg * (math.pi / 180.0)
    f0, f1, f2 = math.cos(p) * c, math.cos(p) * s, math.sin(p)
    basis = np.array([[s, -c, 0.0], [-f2 * c, -f2 * s, f0 * c + f1 * s], [f0, f1, f2]])
    return eye, basis


@njit(cache=True)
def view_matrix(eye, basis):
    """OpenGL's lookAt of the camera (CameraConfig.view_matrix), float32 as PyBullet takes it."""
    m = np.zeros((4, 4))
    for i in range(3):
        sign = -1.0 if i == 2 else 1.0
        for j in range(3):
            m[i, j] = sign * basis[i, j]
    for i in range(3):
        m[i, 3] = -(m[i, 0] * eye[0] + m[i, 1] * eye[1] + m[i, 2] * eye[2])
    m[3, 3] = 1.0
    return m.astype(np.float32)


@njit(cache=True)
def in_wedge(cx, cy, radius, x, y, yaw, hfov, cull):
    """sim/highway/renderer.py Renderer.in_view for one bounding circle: whether it reaches into the view wedge of a
    camera with horizontal field of view hfov [rad] and cull distance `cull` [m] looking along yaw from (x, y)."""
    vx, vy = cx - x, cy - y
    dist = math.hypot(vx, vy)
    bearing = abs((math.atan2(vy, vx) - yaw + np.pi) % (2 * np.pi) - np.pi)
    margin = math.asin(min(max(radius / max(dist, 1e-6), 0.0), 1.0))
    return (dist <= radius or bearing <= hfov / 2 + margin) and dist - radius < cull


@njit(cache=True)
def draw_view(img, chunks, ground, spans, by_rank, colours, x, y, yaw, camera, fx, fy,
              verts, normals, bases, painted, blocks, spheres, firsts, ends, n_chunks, projection,
              car_x, car_y, car_yaw, car_models, car_paints, cars, light, ambient, diffuse):
    """Into img (h, w, 3) uint8, its backdrop: the ground of the chunks `chunks` (bool), polygon p of chunk c and
    rank r listed in by_rank[r, c] (first, end) of `spans` (paint_ground), then their objects (body c: the triangles
    of blocks firsts[c]..ends[c] of `blocks`, culled by their `spheres`) and the cars `cars` (bool; body
    n_chunks + model, paint car_paints (k, 3)), as the camera
    (forward, left, height [m], pitch [deg], near [m]; focal lengths fx, fy [px], `projection` float32) sees them
    from a car at (x, y) [m] with yaw [rad]; returns its z-buffer."""
    zbuf = np.empty(img.shape[:2], dtype=np.float32)
    draw_into(img, zbuf, chunks, ground, spans, by_rank, colours, x, y, yaw, camera, fx, fy, verts, normals, bases,
              painted, blocks, spheres, firsts, ends, n_chunks, projection, car_x, car_y, car_yaw, car_models,
              car_paints, cars, light, ambient, diffuse)
    return zbuf


@njit(cache=True)
def draw_into(img, zbuf, chunks, ground, spans, by_rank, colours, x, y, yaw, camera, fx, fy,
              verts, normals, bases, painted, blocks, spheres, firsts, ends, n_chunks, projection,
              car_x, car_y, car_yaw, car_models, car_paints, cars, light, ambient, diffuse):
    """draw_view with its z-buffer zbuf (h, w) float32 given (any values: it is cleared here): minus the clip-space
    z of what each pixel shows, -inf where nothing."""
    eye, basis = camera_basis(x, y, yaw, camera[0], camera[1], camera[2], camera[3])
    near = camera[4]
    view = view_matrix(eye, basis)
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
    clear = zbuf.reshape(-1)
    for i in range(clear.shape[0]):   # a loop the compiler vectorises (numba's slice assignment does not)
        clear[i] = -np.inf
    eye32 = eye.astype(np.float32)
    identity = np.eye(4, dtype=np.float32)
    none = np.zeros(3, dtype=np.float32)
    still = np.array([1.0, 0.0, 0.0, 0.0])
    pose = np.empty(4)
    for c in range(n_chunks):
        if chunks[c] and ends[c] > firsts[c]:
            draw_body(img, zbuf, verts, normals, bases, painted, blocks, spheres, firsts[c], ends[c], identity, still,
                      none, view, projection, eye32, light, ambient, diffuse, True)
    for k in range(len(car_x)):
        if cars[k]:
            b = n_chunks + car_models[k]
            pose[0], pose[1], pose[2], pose[3] = math.cos(car_yaw[k]), math.sin(car_yaw[k]), car_x[k], car_y[k]
            draw_body(img, zbuf, verts, normals, bases, painted, blocks, spheres, firsts[b], ends[b],
                      car_model(car_x[k], car_y[k], car_yaw[k]), pose, car_paints[k], view, projection, eye32, light,
                      ambient, diffuse, False)


@njit(cache=True)
def keep_depth(depth, zbuf, projection, top, left, mirrored):
    """The objects' depth of a view (its zbuf: minus the clip-space z, -inf where none) into depth (h, w) float32 of
    the frame at (top, left), flipped left to right if `mirrored`, as distances along the view's axis [m] (inf where
    no object): clip z is p22 z + p23 of the eye-space z, which is minus that distance. -inf comes out +inf (p22 is
    negative), so the rows need no test, and the compiler vectorises them."""
    h, w = zbuf.shape
    p22, p23 = projection[2, 2], projection[2, 3]
    scale = np.float32(1.0) / p22
    for r in range(h):
        row, out = zbuf[r], depth[top + r, left:left + w]
        if mirrored:
            out = out[::-1]
        for c in range(w):
            out[c] = (row[c] + p23) * scale


@njit(cache=True)
def to_distance(zbuf, projection):
    """A z-buffer (flat) turned in place into distances along the view's axis [m] as keep_depth turns them."""
    p22, p23 = projection[2, 2], projection[2, 3]
    scale = np.float32(1.0) / p22
    for i in range(zbuf.shape[0]):
        zbuf[i] = (zbuf[i] + p23) * scale


@njit(cache=True)
def draw_frame(frame, insets, offsets, layout, cameras, projections, centres, radii, car_radius,
               ground, spans, by_rank, colours, verts, normals, bases, painted, blocks, spheres, firsts, ends, x, y,
               yaw, car_x, car_y, car_yaw, car_models, car_paints, light, ambient, diffuse, depth):
    """Every view of a frame, as sim/highway/renderer.py composes them: view 0 fills the frame (its backdrop when
    called), each later one is drawn apart, onto its backdrop at insets[offsets[v]:] (height x width x 3 bytes, C
    order), for the caller to paste into the frame (sim/render/raster.py paste: numpy and OpenCV copy rows several
    times faster than a compiled loop of bytes). Per view v: layout[v] (outer top, left, height, width; glass top,
    left, height, width; mirrored), cameras[v] (forward, left, height, pitch, near, fx, fy, yaw offset, hfov, cull)
    and projections[v]. The chunks' bounding circles (centres, radii) and the cars' (car_radius) choose what each
    view draws (in_wedge). depth: the frame's (h, w) float32 objects' distances (keep_depth), or (0, 0) when none is
    wanted."""
    n_chunks = len(radii)
    chunks = np.empty(n_chunks, dtype=np.bool_)
    cars = np.empty(len(car_x), dtype=np.bool_)
    for v in range(len(layout)):
        cam = cameras[v]
        heading = yaw + cam[7]
        for c in range(n_chunks):
            chunks[c] = in_wedge(centres[c, 0], centres[c, 1], radii[c], x, y, heading, cam[8], cam[9])
        for k in range(len(car_x)):
            cars[k] = in_wedge(car_x[k], car_y[k], car_radius, x, y, heading, cam[8], cam[9])
        gt, gl, gh, gw = layout[v, 4], layout[v, 5], layout[v, 6], layout[v, 7]
        img = frame if v == 0 else insets[offsets[v]:offsets[v] + gh * gw * 3].reshape(gh, gw, 3)
        if v == 0 and depth.shape[0]:   # the front view fills the frame: its z-buffer is the depth's array
            draw_into(img, depth, chunks, ground, spans, by_rank, colours, x, y, heading, cam[:5], cam[5], cam[6],
                      verts, normals, bases, painted, blocks, spheres, firsts, ends, n_chunks, projections[v], car_x,
                      car_y, car_yaw, car_models, car_paints, cars, light, ambient, diffuse)
            to_distance(depth.reshape(-1), projections[v])
        else:
            zbuf = draw_view(img, chunks, ground, spans, by_rank, colours, x, y, heading, cam[:5], cam[5], cam[6],
                             verts, normals, bases, painted, blocks, spheres, firsts, ends, n_chunks, projections[v],
                             car_x, car_y, car_yaw, car_models, car_paints, cars, light, ambient, diffuse)
            if depth.shape[0]:
                keep_depth(depth, zbuf, projections[v], gt, gl, layout[v, 8] != 0)
