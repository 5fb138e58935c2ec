"""The compiled rasteriser's scene (renderer "numba", docs/rendering.md#the-fast-renderers): a world's chunks of
ground and objects and its car models packed into arrays once, then a frame of views (the front camera's and the
insets', composed as sim/highway/renderer.py composes PyBullet's) drawn in one compiled call (render), or one view
into an image (draw).
The ground is painted as sim/ground_painter.py paints it (sim/render/raster_ground.py), the objects drawn as
PyBullet's TinyRenderer draws them (sim/render/raster_objects.py), so the frames are those of renderer "tiny" pixel
for pixel but for a rare pixel at an edge, at a fraction of the time.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from sim.camera import CameraConfig
from sim.render.kernel_cache import drop_stale
from sim.render.lighting import base_colour
from sim.render.raster_view import draw_frame, draw_view
from sim.scene import Chunk, Look

KERNELS = ("raster_ground.py", "raster_objects.py", "raster_view.py")   # the compiled functions' files
NO_DEPTH = np.zeros((0, 0), dtype=np.float32)   # draw_frame's depth when none is wanted
BLOCK = 32   # most triangles a culling sphere holds
SPAN = 8.0   # [m] the most a culling sphere's box spans (about a tree), unless one triangle does


def drop_stale_kernels(folder: Path = Path(__file__).parent) -> None:
    """The kernels' cached code is dropped together when any of their files has changed (sim/render/kernel_cache.py)."""
    drop_stale(folder, KERNELS, "raster_*", "raster-kernels.sha1")


drop_stale_kernels()


@dataclass
class Part:
    """A part of a model: a mesh (vertices (n, 3), faces (m, 3), unit vertex normals (n, 3)) and its colour (0-1);
    None: the paint of each car."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    rgb: tuple | None


@dataclass
class Cars:
    """Cars, in the order they are drawn: pose ([m], [rad]), model and paint (indices)."""

    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    models: np.ndarray
    paints: np.ndarray


@dataclass(frozen=True)
class Slot:
    """A view of a frame: its camera, turned by `yaw` [rad] from the car's heading, its image before anything is
    drawn, and where it goes: the first view fills the frame; a later one goes into `glass` (top, left, height,
    width [px]) inside a border filling `outer`, flipped left to right if `mirrored`."""

    camera: CameraConfig
    yaw: float
    backdrop: np.ndarray
    glass: tuple[int, int, int, int]
    outer: tuple[int, int, int, int] = (0, 0, 0, 0)
    mirrored: bool = False


@dataclass
class Layout:
    """A frame's views as the arrays draw_frame takes (Rasteriser.layout)."""

    front: np.ndarray       # the first view's backdrop
    insets: np.ndarray      # every other view's backdrop, flat, one after the other (at offsets[v])
    offsets: np.ndarray
    places: np.ndarray
    cameras: np.ndarray
    projections: np.ndarray
    border: np.ndarray
    pastes: list[tuple]   # per inset: offset in insets, glass (h, w, 3), border image, outer and glass slices, flip


def paste(frame: np.ndarray, insets: np.ndarray, layout: Layout) -> None:
    """Every inset's image (drawn by draw_frame into `insets`) into the frame inside its border, flipped left to right
    by OpenCV straight into the frame where it is a mirror."""
    for offset, shape, bordered, outer, inner, mirrored in layout.pastes:
        image = insets[offset:offset + shape[0] * shape[1] * 3].reshape(shape)
        frame[outer] = bordered   # an image's rows, which numpy copies whole (it broadcasts a colour by bytes)
        if mirrored:
            cv2.flip(image, 1, dst=frame[inner])
        else:
            frame[inner] = image


def _triangles(meshes: list[tuple]) -> tuple[np.ndarray, ...]:
    """Per face corner positions (t, 3, 3), normals (t, 3, 3), base colours (t, 3) and paint flags (t,), float32, of
    meshes given as (vertices, faces, normals, base colour, painted)."""
    v: list[np.ndarray] = [np.zeros((0, 3, 3))]
    n: list[np.ndarray] = [np.zeros((0, 3, 3))]
    c: list[np.ndarray] = [np.zeros((0, 3))]
    p: list[np.ndarray] = [np.zeros(0, bool)]
    for verts, faces, normals, base, painted in meshes:
        f = np.asarray(faces, dtype=np.int64)
        v.append(np.asarray(verts, dtype=np.float32)[f])
        n.append(np.asarray(normals, dtype=np.float32)[f])
        c.append(np.broadcast_to(np.asarray(base, dtype=np.float32), (len(f), 3)))
        p.append(np.full(len(f), painted))
    return tuple(np.ascontiguousarray(np.concatenate(a), dtype=np.float32 if a is not p else bool)
                 for a in (v, n, c, p))


def _ranges(corners: np.ndarray, first: int, end: int) -> list[tuple[int, int]]:
    """Triangles first..end of corners (t, 3, 3) cut in their order into runs of at most BLOCK whose bounding box
    spans at most SPAN [m] (where one triangle alone spans more, that triangle alone)."""
    lo, hi = corners.min(axis=1), corners.max(axis=1)
    out: list[tuple[int, int]] = []
    if end <= first:
        return out
    start, box_lo, box_hi = first, lo[first], hi[first]
    for t in range(first + 1, end):
        new_lo, new_hi = np.minimum(box_lo, lo[t]), np.maximum(box_hi, hi[t])
        if t - start >= BLOCK or (new_hi - new_lo).max() > SPAN:
            out.append((start, t))
            start, new_lo, new_hi = t, lo[t], hi[t]
        box_lo, box_hi = new_lo, new_hi
    out.append((start, end))
    return out


def _blocks(corners: np.ndarray, firsts: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, ...]:
    """Bodies' triangles (body b: firsts[b], counts[b] of corners (t, 3, 3)) cut into blocks (_ranges), each in a
    bounding sphere that each view tests before it transforms a triangle: the blocks' triangle ranges (k, 2),
    spheres (k, 4: centre, radius [m]) and each body's first and end block."""
    per_body = [_ranges(corners, f, f + n) for f, n in zip(firsts, counts)]
    blocks = np.array([r for body in per_body for r in body], dtype=np.int64).reshape(-1, 2)
    spheres = np.zeros((len(blocks), 4))
    for k, (s, e) in enumerate(blocks):
        p = corners[s:e].reshape(-1, 3).astype(np.float64)
        centre = (p.min(axis=0) + p.max(axis=0)) / 2
        spheres[k] = (*centre, np.sqrt(((p - centre) ** 2).sum(axis=1)).max())
    ends = np.cumsum([len(body) for body in per_body]).astype(np.int64)
    return blocks, spheres, ends - [len(body) for body in per_body], ends


class Rasteriser:
    def __init__(self, chunks: list[Chunk], look: Look, materials: tuple[str, ...], models: list[list[Part]],
                 paints=()):
        """materials: the ground materials in painting order; paints: the colours (0-1) a car's paint may take."""
        self.look = look
        # ground polygons in painting order, by material and then by chunk: by_rank[rank, chunk] = (first, end)
        verts: list[np.ndarray] = [np.zeros((0, 3))]
        spans: list[tuple[int, int, int]] = []
        n = 0
        self._by_rank = np.zeros((len(materials), len(chunks), 2), dtype=np.int64)
        for rank, mat in enumerate(materials):
            for ci, chunk in enumerate(chunks):
                self._by_rank[rank, ci, 0] = len(spans)
                for poly in chunk.ground.get(mat, []):
                    verts.append(np.asarray(poly, dtype=np.float64))
                    spans.append((n, n + len(poly), rank))
                    n += len(poly)
                self._by_rank[rank, ci, 1] = len(spans)
        self._ground = np.ascontiguousarray(np.concatenate(verts))
        self._spans = np.array(spans, dtype=np.int64).reshape(-1, 3)
        self._colours = np.array([look.lit(look.colours[m][:3]) for m in materials], dtype=np.int64).reshape(-1, 3)
        # objects: one body per chunk, then one per model, the triangles of each a range of one array
        bodies = [[(m.vertices, m.faces, m.normals, base_colour(look.colours[mat][:3]), False)
                   for mat, m in chunk.objects.items()] for chunk in chunks]
        bodies += [[(p.vertices, p.faces, p.normals, base_colour(p.rgb or (0.0, 0.0, 0.0)), p.rgb is None)
                    for p in parts] for parts in models]
        tris = [_triangles(b) for b in bodies]
        self._v, self._n, self._c, self._p = (np.concatenate([t[i] for t in tris]) for i in range(4))
        counts = np.array([len(t[0]) for t in tris], dtype=np.int64)
        self._blocks, self._spheres, self._first, self._end = _blocks(self._v, np.cumsum(counts) - counts, counts)
        self._n_chunks = len(chunks)
        self._centres = np.array([c.centre for c in chunks], dtype=np.float64).reshape(-1, 2)
        self._radii = np.array([c.radius for c in chunks], dtype=np.float64)
        self._paints = base_colour(np.asarray(paints, dtype=np.float64).reshape(-1, 3))
        self._light = np.asarray(look.light_direction, dtype=np.float32)
        self._ambient, self._diffuse = np.float32(look.ambient), np.float32(look.diffuse)
        self._projections: dict[CameraConfig, tuple] = {}

    def _camera(self, camera: CameraConfig) -> tuple:
        """What a camera's views share: its placement (forward, left, height [m], pitch [deg], near [m]), focal
        lengths [px] and projection (float32, as PyBullet takes it)."""
        if camera not in self._projections:
            f = 1.0 / math.tan(math.radians(camera.fov_deg) / 2)
            self._projections[camera] = (
                np.array([camera.eye_forward, camera.eye_left, camera.eye_height, camera.pitch_deg, camera.near]),
                f / camera.aspect * camera.width / 2, f * camera.height / 2,
                np.array(camera.projection_matrix(), dtype=np.float32).reshape(4, 4).T.copy())
        return self._projections[camera]

    def draw(self, img: np.ndarray, camera: CameraConfig, x: float, y: float, yaw: float, chunks: np.ndarray,
             cars: Cars) -> None:
        """Paint the ground and draw the objects of the chunks `chunks` (bool, in view) and `cars` into img (h, w, 3)
        uint8 RGB, its backdrop, as `camera` sees them from a host car at (x, y) [m] with yaw [rad]."""
        placement, fx, fy, projection = self._camera(camera)
        cx, cy, cyaw, models, paints = self._cars(cars)
        draw_view(img, np.ascontiguousarray(chunks, dtype=np.bool_), self._ground, self._spans, self._by_rank,
                  self._colours, float(x), float(y), float(yaw), placement, fx, fy, self._v, self._n, self._c,
                  self._p, self._blocks, self._spheres, self._first, self._end, self._n_chunks, projection, cx, cy,
                  cyaw, models, paints,
                  np.ones(len(cars.x), dtype=np.bool_), self._light, self._ambient, self._diffuse)

    def _cars(self, cars: Cars) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The kernels' arrays of `cars`: x, y, yaw (float64), model (int64), paint (n, 3 float32 base colours)."""
        paints = self._paints[np.asarray(cars.paints, dtype=np.int64) % len(self._paints)] if len(self._paints) \
            else np.zeros((len(cars.x), 3), np.float32)
        return (np.asarray(cars.x, dtype=np.float64), np.asarray(cars.y, dtype=np.float64),
                np.asarray(cars.yaw, dtype=np.float64), np.asarray(cars.models, dtype=np.int64), paints)

    def layout(self, slots: list[Slot], border) -> Layout:
        """The arrays of a frame of `slots` (the first fills the frame), the insets' border of colour `border`."""
        flat = [np.zeros(0, np.uint8)] + [np.ascontiguousarray(s.backdrop, dtype=np.uint8).reshape(-1)
                                          for s in slots[1:]]
        offsets = np.cumsum([len(b) for b in flat]).astype(np.int64) - [len(b) for b in flat]
        places = np.zeros((len(slots), 9), dtype=np.int64)
        cameras = np.zeros((len(slots), 10))
        projections = np.zeros((len(slots), 4, 4), dtype=np.float32)
        for v, slot in enumerate(slots):
            cam = slot.camera
            places[v] = (*slot.outer, *slot.glass, slot.mirrored)
            placement, fx, fy, projection = self._camera(cam)
            cameras[v] = (*placement, fx, fy, slot.yaw, cam.hfov, cam.cull_distance)
            projections[v] = projection
        pastes = [(int(offsets[v]), (p[6], p[7], 3), np.full((p[2], p[3], 3), border, dtype=np.uint8),
                   (slice(p[0], p[0] + p[2]), slice(p[1], p[1] + p[3])),
                   (slice(p[4], p[4] + p[6]), slice(p[5], p[5] + p[7])), bool(p[8]))
                  for v, p in enumerate(places.tolist()) if v]
        return Layout(np.ascontiguousarray(slots[0].backdrop, dtype=np.uint8), np.concatenate(flat), offsets, places,
                      cameras, projections, np.asarray(border, dtype=np.uint8), pastes)

    def render(self, layout: Layout, x: float, y: float, yaw: float, cars: Cars, car_radius: float,
               depth: np.ndarray | None = None) -> np.ndarray:
        """The frame (h, w, 3) uint8 RGB of `layout`'s views from a host car at (x, y) [m] with yaw [rad], the
        chunks and the cars (bounding circles of car_radius [m]) in each view's wedge drawn in it; `depth` (h, w)
        float32, when given, gets the objects' distances along each view's axis [m] (inf where none)."""
        frame = layout.front.copy()   # numpy's copies: numba's element loops copy bytes ten times slower
        cx, cy, cyaw, models, paints = self._cars(cars)
        insets = layout.insets.copy()
        draw_frame(frame, insets, layout.offsets, layout.places, layout.cameras, layout.projections,
                   self._centres, self._radii, float(car_radius), self._ground, self._spans,
                   self._by_rank, self._colours, self._v, self._n, self._c, self._p, self._blocks, self._spheres,
                   self._first, self._end,
                   float(x), float(y), float(yaw), cx, cy, cyaw, models, paints, self._light, self._ambient,
                   self._diffuse, NO_DEPTH if depth is None else depth)
        paste(frame, insets, layout)
        return frame
