"""What the sidewalk world looks like around a layout: the flat ground (path, kerbs, slab joints, patches of
grass, soil and leaves, shadows) as polygons for the ground painter (sim/ground_painter.py), and the objects
(hedges, bushes, trees, lamp posts, obstacles) as low-poly convex pieces for the object painter
(sim/sidewalk/painter.py). Both are cut into chunks of path so that what is out of view is skipped.

Everything is a function of the layout and the seed: the same world, the same pictures.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.scene import Chunk, road_samples
from sim.sidewalk import shapes
from sim.sidewalk.layout import Layout, Obstacle
from sim.sidewalk.look import SidewalkLook
from sim.sidewalk.shapes import Piece
from sim.track.track import Track

CHUNK_LENGTH = 8.0        # [m] of path per chunk
KERB = (0.12, 0.04)       # [m] kerb top and kerb face widths (sidewalk style), beyond the path's edge
JOINT_WIDTH = 0.025       # [m] slab joints
HEDGE_SAG = 0.01          # [m] a hedge piece's flat face departs from the border's curved face by at most this
# the ground in three passes, each in painting order: details under the path (patches, shadows on the grass), the
# path and its kerbs, details on the path (stains, leaves, joints, shadows); details are skipped beyond DETAIL
GROUND_UNDER = ("grass_dark", "grass_light", "soil", "shadow_grass")
GROUND_BASE = ("kerb_face", "kerb", "path")
GROUND_OVER = ("path_dark", "path_light", "leaves", "joint", "shadow_path")
GROUND = GROUND_UNDER + GROUND_BASE + GROUND_OVER
DETAIL = 25.0             # [m] ground details farther than this are under a pixel: not painted


@dataclass
class SceneChunk:
    ground: Chunk                           # the ground painter's chunk (ground polygons only)
    pieces: list = field(default_factory=list)


# --- ground -------------------------------------------------------------------------------------------------------
def band(track: Track, s: np.ndarray, d_lo, d_hi, z: float = 0.0) -> list[np.ndarray]:
    """Flat polygons (k, 3) between lateral offsets d_lo < d_hi (scalars or per-sample arrays) along samples s;
    one polygon per run of samples where the band is not empty."""
    d_lo = np.broadcast_to(np.asarray(d_lo, dtype=np.float64), s.shape)
    d_hi = np.broadcast_to(np.asarray(d_hi, dtype=np.float64), s.shape)
    ok = d_hi - d_lo > 1e-3
    out = []
    i = 0
    while i < len(s):
        if not ok[i]:
            i += 1
            continue
        j = i
        while j + 1 < len(s) and ok[j + 1]:
            j += 1
        if j > i:
            ss = s[i:j + 1]
            xl, yl, _ = track.pose(ss, d_hi[i:j + 1])
            xr, yr, _ = track.pose(ss, d_lo[i:j + 1])
            out.append(np.column_stack((np.concatenate((xr, xl[::-1])), np.concatenate((yr, yl[::-1])),
                                        np.full(2 * len(ss), z))))
        i = j + 1
    return out


def blob_outline(track: Track, s: float, d: float, a: float, b: float, rng, n: int = 9) -> np.ndarray:
    """A rough ellipse (n, 2) in path coordinates (s, d) around (s, d), half axes a (along) and b (across)."""
    t = np.arange(n) * 2 * math.pi / n + rng.uniform(0, 1)
    r = rng.uniform(0.75, 1.0, n)
    return np.column_stack((s + a * r * np.cos(t), d + b * r * np.sin(t)))


def to_world(track: Track, sd: np.ndarray, z: float = 0.0) -> np.ndarray:
    x, y, _ = track.pose(sd[:, 0], sd[:, 1])
    return np.column_stack((x, y, np.full(len(sd), z)))


def clip_band(sd: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """A polygon in (s, d) clipped to lo <= d <= hi (Sutherland-Hodgman, two half-planes)."""
    pts = sd
    for sign, limit in ((1.0, hi), (-1.0, -lo)):
        out = []
        n = len(pts)
        for i in range(n):
            a, b = pts[i], pts[(i + 1) % n]
            ina, inb = sign * a[1] <= limit, sign * b[1] <= limit
            if ina:
                out.append(a)
            if ina != inb:
                t = (limit - sign * a[1]) / (sign * (b[1] - a[1]))
                out.append(a + t * (b - a))
        pts = np.array(out).reshape(-1, 2)
        if len(pts) < 3:
            return pts
    return pts


def world_to_sd(track: Track, xy: np.ndarray) -> np.ndarray:
    s, d = track.frenet(xy[:, 0], xy[:, 1])
    s = np.asarray(s, dtype=np.float64)
    s = s[0] + track.gap(s[0], s)   # unwrapped around the first point: a polygon may straddle s = 0
    return np.column_stack((s, d))


def _shadow(ground: dict, track: Track, hw: float, sd: np.ndarray) -> None:
    """A shadow polygon in (s, d): all of it on the grass (the path is painted over it), and its part on the
    path again after the path."""
    if len(sd) < 3:
        return
    ground.setdefault("shadow_grass", []).append(to_world(track, sd))
    on_path = clip_band(sd, -hw, hw)
    if len(on_path) >= 3:
        ground.setdefault("shadow_path", []).append(to_world(track, on_path))


def _ground(layout: Layout, look: SidewalkLook, s0: float, s1: float, rng) -> dict:
    path, track = layout.path, layout.path.track
    hw = path.half_width
    s = road_samples(track, s0, s1)
    g: dict = {"path": band(track, s, -hw, hw)}
    if path.style == "sidewalk":
        k, f = KERB
        g["kerb"] = band(track, s, hw, hw + k) + band(track, s, -hw - k, -hw)
        g["kerb_face"] = band(track, s, hw + k, hw + k + f) + band(track, s, -hw - k - f, -hw - k)
        first = math.ceil(s0 / layout_slab(layout)) * layout_slab(layout)
        for a in np.arange(first, s1, layout_slab(layout)):   # slab joints across the path
            g.setdefault("joint", []).extend(band(track, np.array([a, a + JOINT_WIDTH]), -hw, hw))
    length = s1 - s0
    # patches of darker and lighter grass (soil and fallen leaves in forests) beside the path
    for _ in range(rng.poisson(1.2 * length / 4)):
        side = rng.choice([-1.0, 1.0])
        sd = blob_outline(track, rng.uniform(s0, s1), side * (hw + rng.uniform(0.6, 6.0)), rng.uniform(0.6, 2.5),
                          rng.uniform(0.4, 1.5), rng)
        kinds = ("soil", "leaves", "grass_dark") if path.style == "forest" else ("grass_dark", "grass_light",
                                                                                  "grass_dark", "soil")
        g.setdefault(str(rng.choice(kinds)), []).append(to_world(track, sd))
    # stains and repairs on the path; leaves on forest paths
    for _ in range(rng.poisson({"sidewalk": 0.5, "park": 0.8, "forest": 1.6}[path.style] * length / 4)):
        sd = blob_outline(track, rng.uniform(s0, s1), rng.uniform(-hw, hw), rng.uniform(0.15, 0.8),
                          rng.uniform(0.1, 0.5), rng)
        sd = clip_band(sd, -hw, hw)
        if len(sd) >= 3:
            kind = "leaves" if path.style == "forest" and rng.uniform() < 0.5 else \
                ("path_dark" if rng.uniform() < 0.6 else "path_light")
            g.setdefault(kind, []).append(to_world(track, sd))
    return g


def layout_slab(layout: Layout) -> float:
    """[m] slab length of a sidewalk (seeded)."""
    return 1.2 + 0.4 * ((layout.seed * 2654435761) % 1000) / 1000.0


# --- objects ------------------------------------------------------------------------------------------------------
def obstacle_pieces(o: Obstacle) -> list[Piece]:
    """The pieces of an obstacle, built at the origin facing +x and moved into place."""
    p: list[Piece] = []
    if o.kind == "cone":
        p.append(shapes.box(0, 0, 0, 0, 0.28, 0.28, 0.03, "cone"))
        p.append(shapes.cone(0, 0, 0.03, 0.12, 0.15, 6, "cone", top_radius=0.085))
        p.append(shapes.cone(0, 0, 0.18, 0.085, 0.09, 6, "stripe", top_radius=0.065))
        p.append(shapes.cone(0, 0, 0.27, 0.065, 0.18, 6, "cone"))
    elif o.kind == "post":
        p.append(shapes.prism(shapes.polygon(0, 0, 0.06, 6), 0, 0.7, "post", top=False))
        p.append(shapes.prism(shapes.polygon(0, 0, 0.06, 6), 0.7, 0.78, "stripe", top=False))
        p.append(shapes.cone(0, 0, 0.78, 0.06, 0.07, 6, "post", top_radius=0.03))
    elif o.kind == "bench":
        p.append(shapes.prism(shapes.rectangle(0, 0.04, 0, 1.4, 0.4), 0.4, 0.45, "wood", bottom=True))
        p.append(shapes.prism(shapes.rectangle(0, -0.21, 0, 1.4, 0.06), 0.5, 0.8, "wood", bottom=True))
        for x in (-0.6, 0.6):
            p.append(shapes.box(x, 0.0, 0.0, 0, 0.06, 0.46, 0.4, "metal", top=False))
            p.append(shapes.box(x, -0.21, 0.4, 0, 0.05, 0.05, 0.1, "metal", top=False))
    elif o.kind == "bike":
        for x in (-0.55, 0.55):   # wheels: thin 10-gons standing across y
            ring = shapes.polygon(0, 0, 0.33, 10)
            wheel = shapes.prism(np.column_stack((ring[:, 0], ring[:, 1])), -0.02, 0.02, "tyre", bottom=True)
            faces = wheel.faces[..., [0, 2, 1]].copy()   # turn the disc upright: (x, z, y) -> (x, y, z)
            faces[..., 0] += x
            faces[..., 2] += 0.33
            normals = wheel.normals[:, [0, 2, 1]]
            p.append(Piece(faces, normals, "tyre"))
        for (xa, za), (xb, zb) in (((-0.55, 0.33), (-0.1, 0.75)), ((-0.1, 0.75), (0.45, 0.78)),
                                   ((-0.55, 0.33), (0.05, 0.35)), ((0.05, 0.35), (0.45, 0.78)),
                                   ((-0.1, 0.75), (0.05, 0.35)), ((0.45, 0.78), (0.55, 0.33))):
            p.append(_bar(xa, za, xb, zb, 0.035, "bike"))
        p.append(shapes.box(-0.12, 0, 0.8, 0, 0.22, 0.09, 0.04, "metal"))      # saddle
        p.append(shapes.box(0.47, 0, 0.95, 0, 0.04, 0.45, 0.03, "metal"))      # handlebar
        p.append(shapes.box(0.46, 0, 0.78, 0, 0.03, 0.03, 0.17, "bike", top=False))
    elif o.kind == "pedestrian":
        for y in (-0.08, 0.08):
            p.append(shapes.box(0, y, 0.0, 0, 0.13, 0.12, 0.85, "trousers", top=False))
            p.append(shapes.box(0, 1.8 * y + math.copysign(0.1, y), 0.8, 0, 0.1, 0.09, 0.6, "shirt"))
        p.append(shapes.prism(shapes.rectangle(0, 0, 0, 0.24, 0.38), 0.85, 1.45, "shirt", bottom=True))
        p.append(shapes.box(0, 0, 1.45, 0, 0.08, 0.08, 0.06, "skin", top=False))
        p.append(shapes.blob(0, 0, 1.6, 0.1, 0.09, 0.12, "skin"))
    return [q.moved(o.x, o.y, o.world_yaw) for q in p]


def _bar(xa: float, za: float, xb: float, zb: float, t: float, material: str) -> Piece:
    """A thin square bar in the x-z plane from (xa, za) to (xb, zb)."""
    ux, uz = xb - xa, zb - za
    n = math.hypot(ux, uz)
    px, pz = -uz / n * t / 2, ux / n * t / 2
    quad = np.array([[xa + px, za + pz], [xb + px, zb + pz], [xb - px, zb - pz], [xa - px, za - pz]])
    lo = np.column_stack((quad[:, 0], np.full(4, -t / 2), quad[:, 1]))
    hi = np.column_stack((quad[:, 0], np.full(4, t / 2), quad[:, 1]))
    polys = [lo, hi] + [[lo[i], lo[(i + 1) % 4], hi[(i + 1) % 4], hi[i]] for i in range(4)]
    return shapes._piece(polys, material, ((xa + xb) / 2, 0.0, (za + zb) / 2))


def lead_pieces() -> list[Piece]:
    """The lead car at the origin facing +x: body, deck, wheels."""
    return [shapes.box(0, 0, 0.045, 0, 0.45, 0.19, 0.08, "lead"),
            shapes.box(-0.04, 0, 0.125, 0, 0.24, 0.15, 0.06, "lead_dark"),
            *[shapes.box(x, y, 0.0, 0, 0.11, 0.05, 0.1, "lead_dark") for x in (-0.14, 0.14) for y in (-0.09, 0.09)]]


def border_pieces(layout: Layout, k: int, side: int, rng) -> list[tuple[float, Piece]]:
    """The hedge or bushes of stretch k of a border, each with its s [m]; every piece touches the face from
    behind."""
    track = layout.path.track
    b = layout.borders[side]
    s0, s1, face, kind = b.starts[k], b.ends[k], b.face[k], b.kinds[k]
    h, depth, sign = b.heights[k], b.depths[k], b.side
    out: list[tuple[float, Piece]] = []
    if kind == "hedge":
        s = s0
        while s < s1 - 1e-6:
            r = abs(1.0 / track.curvature(s) - face) if track.curvature(s) else math.inf
            e = min(s + min(float(rng.uniform(0.5, 1.0)), math.sqrt(8 * r * HEDGE_SAG)), s1)
            i = int(np.searchsorted(track.starts, s, side="right"))
            if i < len(track.starts) and s + 0.02 < track.starts[i] < e:   # a piece never bends over a joint
                e = float(track.starts[i])
            ss = np.array([s, e, e, s])
            dd = np.array([face, face, face + sign * depth, face + sign * depth])
            x, y, _ = track.pose(ss, dd)
            top = h * float(rng.uniform(0.9, 1.08))       # clipped unevenly: a hedge's top is never flat
            piece = shapes.prism(np.column_stack((x, y)), 0.0, top, "hedge")
            piece.shades = np.full(len(piece.faces), float(rng.uniform(0.8, 1.15)))
            out.append((s, piece))
            s = e
    else:
        s = s0
        while s < s1:
            r = float(rng.uniform(0.3, 0.55))
            a = s + r * 0.8
            if a > s1:
                break
            rz = min(h, 2 * r) / 2 * float(rng.uniform(0.9, 1.15))
            x, y, yaw = track.pose(a, face + sign * r)
            piece = shapes.dome(x, y, r, 2 * rz, "bush_a" if rng.uniform() < 0.6 else "bush_b",
                                yaw=float(rng.uniform(0, 6.3)))
            piece.shades = rng.uniform(0.85, 1.12, len(piece.faces))
            out.append((a, piece))
            s = a + r * float(rng.uniform(0.5, 1.0))
    return out


def tree_pieces(t, rng) -> list[Piece]:
    if t.conifer:
        base = t.height * 0.15
        out = [shapes.prism(shapes.polygon(t.x, t.y, t.trunk, 5), 0.0, base + 0.1, "trunk", top=False),
               shapes.cone(t.x, t.y, base, t.crown, t.height * 0.55, 7, "conifer"),
               shapes.cone(t.x, t.y, base + t.height * 0.4, t.crown * 0.7, t.height * 0.6, 7, "conifer")]
    else:
        trunk_h = max(1.5, t.height - 1.7 * t.crown)
        out = [shapes.prism(shapes.polygon(t.x, t.y, t.trunk, 5), 0.0, trunk_h + 0.3 * t.crown, "trunk", top=False),
               shapes.blob(t.x, t.y, trunk_h + 0.75 * t.crown, t.crown, t.crown, t.crown * 0.85,
                           "foliage_a" if rng.uniform() < 0.55 else "foliage_b", yaw=float(rng.uniform(0, 6.3)))]
        out[-1].shades = rng.uniform(0.85, 1.1, len(out[-1].faces))
    return out


def lamp_pieces(x: float, y: float) -> list[Piece]:
    return [shapes.prism(shapes.polygon(x, y, 0.05, 6), 0.0, 3.6, "lamp", top=False),
            shapes.box(x, y, 3.6, 0.0, 0.25, 0.25, 0.18, "lamp")]


def _shadows(ground: dict, layout: Layout, look: SidewalkLook, trees, obstacles, borders) -> None:
    """Shadows on the ground (none under an overcast sky): tree crowns, obstacles, hedges and bushes. A shadow is
    painted whole under the path, and its part on the path again over it."""
    if look.shadow_length <= 0:
        return
    track, hw = layout.path.track, layout.path.half_width
    v = look.shadow_vector(1.0)
    along = v / (np.linalg.norm(v) or 1.0)
    across = np.array([-along[1], along[0]])
    stretch = min(2.5, math.hypot(1.0, look.shadow_length))
    a = np.arange(10) * 2 * math.pi / 10
    on_path = []                                   # world polygons that may reach onto the path
    for t, d_tree in trees:
        centre = np.array([t.x, t.y]) + look.shadow_vector(t.height - t.crown)
        r = t.crown * (0.8 if t.conifer else 1.0)
        pts = centre + np.outer(np.cos(a) * r * stretch, along) + np.outer(np.sin(a) * r, across)
        ground.setdefault("shadow_grass", []).append(np.column_stack((pts, np.zeros(len(pts)))))
        if abs(d_tree) - hw < r * stretch + np.linalg.norm(centre - (t.x, t.y)) + 0.5:
            on_path.append(pts)
    for o in obstacles:
        foot = shapes.rectangle(o.x, o.y, o.world_yaw, o.length, o.width)
        on_path.append(_hull(np.concatenate((foot, foot + look.shadow_vector(o.height * (0.6 if o.kind == "bench"
                                                                                         else 0.9))))))
    if on_path:   # one projection onto the path for all of them
        sd = world_to_sd(track, np.concatenate(on_path))
        i = 0
        for pts in on_path:
            part = sd[i:i + len(pts)]
            part[:, 0] = part[0, 0] + track.gap(part[0, 0], part[:, 0])
            clipped = clip_band(part, -hw, hw)
            if len(clipped) >= 3:
                ground.setdefault("shadow_path", []).append(to_world(track, clipped))
            i += len(pts)
    for side, k, s0, s1 in borders:
        b = layout.borders[side]
        s = road_samples(track, s0, s1)
        _, _, tangent = track.pose(s)
        v = look.shadow_vector(b.heights[k] * (1.0 if b.kinds[k] == "hedge" else 0.75))
        lateral = -np.sin(tangent) * v[0] + np.cos(tangent) * v[1]   # shadow's reach along +d
        face = b.face[k]
        lo, hi = np.minimum(face, face + lateral), np.maximum(face, face + lateral)
        ground.setdefault("shadow_grass", []).extend(band(track, s, lo, hi))
        ground.setdefault("shadow_path", []).extend(band(track, s, np.maximum(lo, -hw), np.minimum(hi, hw)))


def _hull(pts: np.ndarray) -> np.ndarray:
    """Convex hull (monotone chain) of 2-D points, counter-clockwise."""
    ordered = sorted(map(tuple, pts))

    def half(points: list[tuple]) -> list[tuple]:
        out: list[tuple] = []
        for p in points:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out
    lower, upper = half(ordered), half(ordered[::-1])
    return np.array(lower[:-1] + upper[:-1])


def build_scenery(layout: Layout, look: SidewalkLook) -> list[SceneChunk]:
    """The whole loop's ground and objects in chunks along s."""
    path, track = layout.path, layout.path.track
    rng = np.random.default_rng([layout.seed, 0x5CE])
    n = max(1, int(round(path.length / CHUNK_LENGTH)))
    edges = np.linspace(0.0, path.length, n + 1)

    def chunk_of(s) -> np.ndarray:
        return np.clip(np.searchsorted(edges, np.asarray(s) % path.length, side="right") - 1, 0, n - 1)

    pieces: list[list[Piece]] = [[] for _ in range(n)]
    trees_in: list[list] = [[] for _ in range(n)]
    obst_in: list[list] = [[] for _ in range(n)]
    borders_in: list[list] = [[] for _ in range(n)]
    if layout.trees:
        ts, td = track.frenet(np.array([t.x for t in layout.trees]), np.array([t.y for t in layout.trees]))
        for t, c, d in zip(layout.trees, chunk_of(ts), np.atleast_1d(td).tolist()):
            pieces[c].extend(tree_pieces(t, rng))
            trees_in[c].append((t, d))
    if layout.lamps:
        ls, _ = track.frenet(np.array([p[0] for p in layout.lamps]), np.array([p[1] for p in layout.lamps]))
        for (x, y), c in zip(layout.lamps, chunk_of(ls)):
            pieces[c].extend(lamp_pieces(x, y))
    for o in layout.obstacles:
        c = int(chunk_of(o.s))
        pieces[c].extend(obstacle_pieces(o))
        obst_in[c].append(o)
    for side in (0, 1):
        b = layout.borders[side]
        for k in range(len(b.starts)):
            for s_piece, piece in border_pieces(layout, k, side, rng):
                pieces[int(chunk_of(s_piece))].append(piece)
            for c in range(int(chunk_of(b.starts[k])), int(chunk_of(b.ends[k] - 1e-6)) + 1):
                borders_in[c].append((side, k, max(b.starts[k], edges[c]), min(b.ends[k], edges[c + 1])))
    out = []
    for c, (s0, s1) in enumerate(zip(edges[:-1], edges[1:])):
        ground = _ground(layout, look, s0, s1, rng)
        _shadows(ground, layout, look, trees_in[c], obst_in[c], borders_in[c])
        xy = np.vstack([p[:, :2] for ps in ground.values() for p in ps]
                       + [p.faces.reshape(-1, 3)[:, :2] for p in pieces[c]])
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        out.append(SceneChunk(Chunk((lo + hi) / 2, float(np.linalg.norm(hi - lo) / 2), ground, {}), pieces[c]))
    return out
