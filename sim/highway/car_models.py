"""Low-poly car models made with trimesh (about 150 triangles each).

Car frame: x forward, y left, z up, origin at the centre of the footprint on the ground. Every model is a
few parts, one colour each (paint, glass, tyres, tail lights, head lights), so the renderer can recolour the
paint per car. Footprints are shared with the collision test and SUMO's vehicle types.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
import trimesh

from sim.highway.footprints import FOOTPRINTS
from sim.highway.mesh import MeshData

PARTS = ("paint", "glass", "tyres", "taillights", "headlights")   # every model's, the painted one first
PART_COLOURS = {  # RGBA of the parts that do not take the car's paint
    "glass": (0.10, 0.12, 0.16, 1.0),
    "tyres": (0.05, 0.05, 0.05, 1.0),
    "taillights": (0.75, 0.05, 0.05, 1.0),
    "headlights": (0.95, 0.93, 0.80, 1.0),
}

PAINTS = [  # RGB
    (0.80, 0.10, 0.10), (0.10, 0.25, 0.70), (0.92, 0.92, 0.92), (0.12, 0.12, 0.12), (0.55, 0.57, 0.60),
    (0.95, 0.75, 0.10), (0.10, 0.45, 0.20), (0.60, 0.10, 0.35), (0.95, 0.45, 0.10), (0.35, 0.65, 0.85),
    (0.45, 0.30, 0.15), (0.75, 0.75, 0.55),
]


def car_colours(tint: tuple | None = None) -> tuple[list, dict]:
    """The paints and the parts' colours in a light of colour `tint` (a condition's low sun: warm); None: as they
    are."""
    if tint is None:
        return PAINTS, PART_COLOURS
    paints = [tuple(float(c * t) for c, t in zip(p, tint)) for p in PAINTS]
    parts = {k: tuple(float(c * t) for c, t in zip(v[:3], tint)) + (v[3],) for k, v in PART_COLOURS.items()}
    return paints, parts


@dataclass(frozen=True)
class CarModel:
    name: str
    length: float   # [m]
    width: float    # [m]
    height: float   # [m]
    parts: dict     # part name -> MeshData (flat-shaded, outward-facing)


def _orient_outward(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Flip faces of a convex part that point inwards (the renderer culls back faces)."""
    centre = mesh.vertices.mean(axis=0)
    tri = mesh.vertices[mesh.faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    inward = np.einsum("ij,ij->i", normal, tri.mean(axis=1) - centre) < 0
    faces = mesh.faces.copy()
    faces[inward] = faces[inward][:, ::-1]
    return trimesh.Trimesh(mesh.vertices, faces, process=False)


def prism(profile_xz, y0: float, y1: float) -> trimesh.Trimesh:
    """A convex side profile [(x, z), ...] extruded across y0..y1 [m]."""
    p = np.asarray(profile_xz, dtype=np.float64)
    n = len(p)
    verts = np.vstack([np.c_[p[:, 0], np.full(n, y0), p[:, 1]], np.c_[p[:, 0], np.full(n, y1), p[:, 1]]])
    faces = [[0, i, i + 1] for i in range(1, n - 1)] + [[n, n + i, n + i + 1] for i in range(1, n - 1)]
    for i in range(n):
        j = (i + 1) % n
        faces += [[i, j, n + j], [i, n + j, n + i]]
    return _orient_outward(trimesh.Trimesh(verts, faces, process=False))


def _box(centre, size) -> trimesh.Trimesh:
    b = trimesh.creation.box(extents=size)
    b.apply_translation(centre)
    return b


def _join(meshes: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """One mesh of several (trimesh declares the result a Geometry; meshes make a mesh)."""
    out = trimesh.util.concatenate(meshes)
    assert isinstance(out, trimesh.Trimesh)
    return out


def _make(name, length, width, height, nose, tail, belt, cabin, clearance=0.22, wheel_r=0.33):
    """nose/tail: how far the bonnet and boot drop [m]; belt: waist height; cabin: (x_back, x_front,
    x_roof_back, x_roof_front) of the glasshouse."""
    hl, hw = length / 2, width / 2
    body = prism([(-hl, clearance), (hl, clearance), (hl, belt - nose), (hl - 0.6, belt), (-hl + 0.35, belt),
                  (-hl, belt - tail)], -hw, hw)
    xb, xf, rb, rf = cabin
    glass = prism([(xb, belt), (xf, belt), (rf, height), (rb, height)], -hw + 0.12, hw - 0.12)
    wheels = []
    for x in (hl - 0.85, -hl + 0.8):
        for y in (hw - 0.2, -hw + 0.2):
            w = trimesh.creation.cylinder(radius=wheel_r, height=0.22, sections=8)
            w.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
            w.apply_translation([x, y, wheel_r])
            wheels.append(w)
    tail_z = belt - tail - 0.12
    taillights = _join([_box([-hl - 0.01, s * (hw - 0.3), tail_z], [0.04, 0.35, 0.14])
                                           for s in (1, -1)])
    head_z = belt - nose - 0.1
    headlights = _join([_box([hl + 0.01, s * (hw - 0.3), head_z], [0.04, 0.35, 0.12])
                                           for s in (1, -1)])
    parts = {"paint": body, "glass": glass, "tyres": _join(wheels),
             "taillights": taillights, "headlights": headlights}
    return CarModel(name, length, width, height, {k: MeshData.from_trimesh(v) for k, v in parts.items()})


@cache
def car_models() -> tuple[CarModel, ...]:
    return (
        _make("sedan", *FOOTPRINTS["sedan"], 1.45, nose=0.25, tail=0.1, belt=0.95,
              cabin=(-1.35, 0.95, -0.85, 0.15)),
        _make("hatchback", *FOOTPRINTS["hatchback"], 1.5, nose=0.25, tail=0.05, belt=0.95,
              cabin=(-1.95, 0.75, -1.75, 0.0)),
        _make("suv", *FOOTPRINTS["suv"], 1.78, nose=0.15, tail=0.05, belt=1.15, cabin=(-2.2, 0.9, -2.1, 0.2)),
        _make("van", *FOOTPRINTS["van"], 2.05, nose=0.2, tail=0.0, belt=1.1, cabin=(-2.4, 1.6, -2.4, 1.2),
              wheel_r=0.35),
        _make("coupe", *FOOTPRINTS["coupe"], 1.22, nose=0.2, tail=0.1, belt=0.82, cabin=(-1.1, 0.7, -0.6, 0.0)),
    )
