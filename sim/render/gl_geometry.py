"""Ground polygons and meshes as the vertex rows of sim/render/gl_programs.py: position, normal, colour, kind, rank."""
from __future__ import annotations

import numpy as np

from sim.render.gl_programs import GROUND

VERTEX_FORMAT = "3f 3f 3f 1f 1f"   # position, normal, colour (0-255), kind, rank
VERTEX_ATTRIBUTES = ("in_position", "in_normal", "in_colour", "in_kind", "in_rank")
WIDTH = 11   # floats a vertex


def ribbon_triangles(polygon: np.ndarray) -> np.ndarray:
    """A flat band given as one polygon (2n, 3), its right boundary forwards and then its left boundary backwards
    (sim/highway/scenery.py ribbon), as triangles (2(n-1), 3, 3), each counter-clockwise seen from above: the camera
    is always above the ground, so every ground triangle faces it."""
    p = np.asarray(polygon, dtype=np.float64)
    if len(p) % 2 or len(p) < 4:
        raise ValueError(f"a ground polygon is a ribbon of 2n >= 4 points, got {len(p)}")
    n = len(p) // 2
    right, left = p[:n], p[n:][::-1]
    tris = np.concatenate([np.stack([right[:-1], right[1:], left[1:]], axis=1),
                           np.stack([right[:-1], left[1:], left[:-1]], axis=1)])
    e1, e2 = tris[:, 1, :2] - tris[:, 0, :2], tris[:, 2, :2] - tris[:, 0, :2]
    clockwise = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    tris[clockwise] = tris[clockwise][:, ::-1]
    return tris


def ground_rows(points: np.ndarray, rank: int, rgb) -> np.ndarray:
    """Vertex rows of ground primitives (triangles (m, 3, 3), segments (m, 2, 3)) of painting rank `rank` and colour
    `rgb` (0-255, as painted)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    rows = np.zeros((len(pts), WIDTH), dtype=np.float32)
    rows[:, 0:3] = pts
    rows[:, 6:9] = np.asarray(rgb, dtype=np.float32)
    rows[:, 9] = GROUND
    rows[:, 10] = rank
    return rows


def outline_rows(polygon: np.ndarray, rank: int, rgb) -> np.ndarray:
    """Vertex rows of a ground polygon's closed outline as line segments (2k, one pair per edge). Drawn besides its
    triangles, they give a band narrower than a pixel the pixels the painter's fill gives it (OpenCV fills every
    pixel row an edge crosses), where triangles alone cover only the pixel centres inside: far lane markings."""
    p = np.asarray(polygon, dtype=np.float64)
    return ground_rows(np.stack([p, np.roll(p, -1, axis=0)], axis=1), rank, rgb)


def mesh_rows(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray, base, kind: float) -> np.ndarray:
    """Vertex rows of a mesh's triangles, one row per face corner: vertices (n, 3), faces (m, 3), unit vertex
    normals (n, 3); `base` its colour before lighting (0-255, programs.base_colour); `kind` OBJECT or PAINTED."""
    idx = np.asarray(faces, dtype=np.int64).reshape(-1)
    rows = np.zeros((len(idx), WIDTH), dtype=np.float32)
    rows[:, 0:3] = np.asarray(vertices, dtype=np.float64)[idx]
    rows[:, 3:6] = np.asarray(normals, dtype=np.float64)[idx]
    rows[:, 6:9] = np.asarray(base, dtype=np.float32)
    rows[:, 9] = kind
    return rows
