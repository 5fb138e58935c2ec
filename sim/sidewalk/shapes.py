"""Low-poly convex solids as flat faces, for the object painter (sim/sidewalk/painter.py).

A piece is one convex solid: its faces (F, 4, 3) [m], counter-clockwise seen from outside (a triangle repeats
its last corner), and their outward unit normals (F, 3). Seen from anywhere, the faces of a convex solid that
face the eye never overlap on screen, so a piece needs no sorting inside itself; pieces are painted far to near.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class Piece:
    faces: np.ndarray      # (F, 4, 3)
    normals: np.ndarray    # (F, 3)
    material: str
    shades: np.ndarray | None = None   # (F,) per-face brightness factor (two-tone bushes); None: 1
    far: Piece | None = None         # a simpler stand-in painted from afar (sim/sidewalk/painter.py)

    @property
    def centre(self) -> np.ndarray:
        return self.faces.reshape(-1, 3).mean(axis=0)

    def moved(self, x: float, y: float, yaw: float) -> Piece:
        c, s = math.cos(yaw), math.sin(yaw)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return Piece(self.faces @ rot.T + (x, y, 0.0), self.normals @ rot.T, self.material, self.shades,
                     None if self.far is None else self.far.moved(x, y, yaw))


def _piece(polys: list, material: str, centre) -> Piece:
    """Faces from polygons (3 or 4 corners each) with their normals pointing away from `centre` (the painter culls
    by normals, so the corners' order does not matter)."""
    faces = np.empty((len(polys), 4, 3))
    for i, p in enumerate(polys):
        p = np.asarray(p, dtype=np.float64)
        faces[i, :len(p)] = p
        faces[i, len(p):] = p[-1]
    n = np.cross(faces[:, 1] - faces[:, 0], faces[:, 2] - faces[:, 0])
    outward = np.einsum("ij,ij->i", n, faces.mean(axis=1) - np.asarray(centre, dtype=np.float64)) >= 0
    n = np.where(outward[:, None], n, -n)
    return Piece(faces, n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12), material)


def prism(base: np.ndarray, z0: float, z1: float, material: str, top: bool = True, bottom: bool = False) -> Piece:
    """A vertical prism over a convex base polygon (n, 2) [m] from height z0 to z1."""
    base = np.asarray(base, dtype=np.float64)
    n = len(base)
    lo = np.column_stack((base, np.full(n, z0)))
    hi = np.column_stack((base, np.full(n, z1)))
    polys = [[lo[i], lo[(i + 1) % n], hi[(i + 1) % n], hi[i]] for i in range(n)]
    if top:
        polys += _fan(hi)
    if bottom:
        polys += _fan(lo)
    return _piece(polys, material, (*base.mean(axis=0), (z0 + z1) / 2))


def _fan(ring: np.ndarray) -> list:
    """A convex polygon as quads and triangles sharing its first corner."""
    out, i = [], 1
    while i + 1 < len(ring):
        out.append(ring[[0, i, i + 1, i + 2]] if i + 2 < len(ring) else ring[[0, i, i + 1]])
        i += 2
    return out


def rectangle(x: float, y: float, yaw: float, length: float, width: float) -> np.ndarray:
    """(4, 2) corners of a rectangle centred at (x, y), its length along yaw."""
    c, s = math.cos(yaw), math.sin(yaw)
    local = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], dtype=np.float64) * (length / 2, width / 2)
    return np.column_stack((x + c * local[:, 0] - s * local[:, 1], y + s * local[:, 0] + c * local[:, 1]))


def polygon(x: float, y: float, radius: float, sides: int, phase: float = 0.0) -> np.ndarray:
    a = phase + np.arange(sides) * 2 * math.pi / sides
    return np.column_stack((x + radius * np.cos(a), y + radius * np.sin(a)))


def box(x, y, z0, yaw, length, width, height, material, top=True) -> Piece:
    return prism(rectangle(x, y, yaw, length, width), z0, z0 + height, material, top=top)


def cone(x: float, y: float, z0: float, radius: float, height: float, sides: int, material: str,
         top_radius: float = 0.0, phase: float = 0.0) -> Piece:
    """A pyramid (or a frustum with top_radius > 0) over a regular polygon."""
    lo = np.column_stack((polygon(x, y, radius, sides, phase), np.full(sides, z0)))
    if top_radius <= 0:
        apex = np.array([x, y, z0 + height])
        polys = [[lo[i], lo[(i + 1) % sides], apex] for i in range(sides)]
    else:
        hi = np.column_stack((polygon(x, y, top_radius, sides, phase), np.full(sides, z0 + height)))
        polys = [[lo[i], lo[(i + 1) % sides], hi[(i + 1) % sides], hi[i]] for i in range(sides)] + _fan(hi)
    return _piece(polys, material, (x, y, z0 + height / 3))


_ICO = None


def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    global _ICO
    if _ICO is None:
        t = (1 + 5 ** 0.5) / 2
        v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
                      [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], dtype=np.float64)
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                      [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
                      [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
        _ICO = (v, f)
    return _ICO


def blob(x: float, y: float, z: float, rx: float, ry: float, rz: float, material: str, yaw: float = 0.0,
         below: float | None = None) -> Piece:
    """An icosahedron scaled to radii (rx, ry, rz) [m] around (x, y, z): crowns and bushes. Faces entirely
    below height `below` (hidden in the ground) are dropped."""
    v, f = _icosahedron()
    c, s = math.cos(yaw), math.sin(yaw)
    p = v * (rx, ry, rz)
    p = np.column_stack((c * p[:, 0] - s * p[:, 1] + x, s * p[:, 0] + c * p[:, 1] + y, p[:, 2] + z))
    polys = [p[tri] for tri in f if below is None or p[tri][:, 2].max() > below]
    return _piece(polys, material, (x, y, z))


def dome(x: float, y: float, radius: float, height: float, material: str, yaw: float = 0.0,
         sides: int = 5) -> Piece:
    """A bush: a low-poly dome on the ground (a ring bulging out at a third of its height, a flat top), with an
    octahedral stand-in for afar."""
    a = yaw + np.arange(sides) * 2 * math.pi / sides
    ring = lambda r, z: np.column_stack((x + r * np.cos(a), y + r * np.sin(a), np.full(sides, z)))   # noqa: E731
    lo, mid, hi = ring(0.8 * radius, 0.0), ring(radius, 0.4 * height), ring(0.55 * radius, height)
    polys = [[lo[i], lo[(i + 1) % sides], mid[(i + 1) % sides], mid[i]] for i in range(sides)]
    polys += [[mid[i], mid[(i + 1) % sides], hi[(i + 1) % sides], hi[i]] for i in range(sides)]
    polys += _fan(hi)
    piece = _piece(polys, material, (x, y, 0.45 * height))
    b = yaw + np.arange(4) * math.pi / 2
    far = np.column_stack((x + radius * np.cos(b), y + radius * np.sin(b), np.full(4, 0.4 * height)))
    top = np.array([x, y, height])
    piece.far = _piece([[far[i], far[(i + 1) % 4], top] for i in range(4)], material, (x, y, 0.3 * height))
    return piece


def concat(pieces: list[Piece]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(faces (F, 4, 3), normals (F, 3), piece index per face (F,)) of a list of pieces."""
    faces = np.concatenate([p.faces for p in pieces]) if pieces else np.zeros((0, 4, 3))
    normals = np.concatenate([p.normals for p in pieces]) if pieces else np.zeros((0, 3))
    index = np.concatenate([np.full(len(p.faces), i) for i, p in enumerate(pieces)]) if pieces else np.zeros(0, int)
    return faces, normals, index
