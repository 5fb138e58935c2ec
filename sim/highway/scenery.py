"""What the world looks like: the seeded look (colours, light) and the static geometry around a track.

Geometry is cut into chunks of road so the renderer can skip what is out of view. It comes in two layers
(docs/rendering.md): the flat ground (asphalt, verges, markings, grass patches) as polygons in the road
plane, painted in image space; and the 3-D objects (trees, poles, buildings, guard rails) as meshes for
PyBullet. Open grass and sky are a backdrop, not geometry.
"""
from __future__ import annotations

import math

import numpy as np
import trimesh

from sim.highway.mesh import MeshData
from sim.scene import Chunk, Look, road_samples
from sim.track import VERGE_WIDTH, Track

CHUNK_LENGTH = 40.0       # [m] of road per chunk
DASH = (4.0, 10.0)        # [m] dash length, dash period of the markings between lanes
MARKING_WIDTH = 0.15      # [m]
MARKING_LIFT = 0.03       # [m] above the asphalt, against depth fighting


GROUND_MATERIALS = ("asphalt", "verge", "patch_dark", "patch_light", "marking")  # in painting order


def make_look(seed: int, sky: str | None = None) -> Look:
    """The seed's palette and light: a clear or an overcast sky drawn from the seed, or the one `sky` names ("clear"
    or "overcast": the same draws, the sky's kept or overridden, so a seed that draws a clear sky looks the same
    either way)."""
    rng = np.random.default_rng([int(seed), 0x100C])
    grey = rng.uniform(0.24, 0.40)
    asphalt = (grey, grey, grey * rng.uniform(1.0, 1.08), 1.0)
    dry = rng.uniform(0.0, 1.0)
    grass = (0.22 + 0.25 * dry, 0.45 + 0.05 * dry, 0.15 + 0.05 * dry)
    verge = tuple(np.r_[np.array([0.55, 0.50, 0.42]) * rng.uniform(0.8, 1.1), 1.0])
    drawn = rng.uniform() < 0.3   # drawn whatever `sky` says: the draws after it stay the seed's
    overcast = drawn if sky is None else sky == "overcast"
    sky_top = (0.62, 0.65, 0.70) if overcast else (0.25, 0.45, 0.85)
    sky_horizon = (0.85, 0.86, 0.88) if overcast else (0.72, 0.82, 0.95)
    az, el = rng.uniform(0, 2 * math.pi), rng.uniform(math.radians(25), math.radians(75))
    buildings = [tuple(np.r_[rng.uniform(0.35, 0.85, 3), 1.0]) for _ in range(3)]
    colours = {
        "asphalt": asphalt, "verge": verge, "marking": (0.95, 0.95, 0.93, 1.0),
        "patch_dark": tuple(np.r_[np.array(grass) * 0.82, 1.0]),
        "patch_light": tuple(np.r_[np.clip(np.array(grass) * 1.15, 0, 1), 1.0]),
        "trunk": (0.35, 0.25, 0.15, 1.0),
        "foliage_a": (0.10, 0.32 + 0.1 * rng.uniform(), 0.12, 1.0),
        "foliage_b": (0.25 + 0.15 * dry, 0.45, 0.12, 1.0),
        "pole": (0.55, 0.56, 0.58, 1.0), "barrier": (0.70, 0.72, 0.75, 1.0),
        "building_a": buildings[0], "building_b": buildings[1], "building_c": buildings[2],
        "roof": (0.30, 0.22, 0.20, 1.0),
    }
    light = (math.cos(az) * math.cos(el), math.sin(az) * math.cos(el), math.sin(el))
    return Look(colours, sky_top, sky_horizon, grass, light,
                ambient=float(rng.uniform(0.5, 0.65)) if not overcast else 0.75,
                diffuse=float(rng.uniform(0.3, 0.45)) if not overcast else 0.2)


# --- road ----------------------------------------------------------------------------------------------------
def ribbon(track: Track, s: np.ndarray, d_left: float, d_right: float, z: float = 0.0) -> np.ndarray:
    """A flat band between two lateral offsets along the samples s, as one polygon (2n, 3): the right
    boundary forwards, then the left boundary backwards."""
    xl, yl, _ = track.pose(s, np.full_like(s, d_left))
    xr, yr, _ = track.pose(s, np.full_like(s, d_right))
    zs = np.full(2 * len(s), z)
    return np.c_[np.r_[xr, xl[::-1]], np.r_[yr, yl[::-1]], zs]


def wall(track: Track, s: np.ndarray, d: float, height: float) -> MeshData:
    """A vertical two-sided ribbon at lateral offset d (guard rails)."""
    x, y, h = track.pose(s, np.full_like(s, d))
    n = len(s)
    v = np.empty((2 * n, 3))
    v[0::2] = np.c_[x, y, np.zeros(n)]
    v[1::2] = np.c_[x, y, np.full(n, height)]
    i = np.arange(n - 1) * 2
    front = np.vstack([np.c_[i, i + 2, i + 3], np.c_[i, i + 3, i + 1]])
    normal = np.c_[-np.sin(h), np.cos(h), np.zeros(n)].repeat(2, axis=0)
    one = MeshData(v, front, normal)
    back = MeshData(v.copy(), front[:, ::-1], -normal)
    return MeshData.concat([one, back])


def _road_polygons(track: Track, s0: float, s1: float) -> dict:
    s = road_samples(track, s0, s1)
    m = track.markings
    hw = MARKING_WIDTH / 2
    out = {
        "asphalt": [ribbon(track, s, m[0], m[-1])],
        "verge": [ribbon(track, s, m[0] + VERGE_WIDTH, m[0]), ribbon(track, s, m[-1], m[-1] - VERGE_WIDTH)],
        "marking": [ribbon(track, s, m[0] - 0.1 + hw, m[0] - 0.1 - hw, MARKING_LIFT),
                    ribbon(track, s, m[-1] + 0.1 + hw, m[-1] + 0.1 - hw, MARKING_LIFT)],
    }
    dash, period = DASH
    first = math.ceil(s0 / period) * period
    for a in np.arange(first, s1, period):
        ds = np.array([a, a + dash / 2, a + dash])
        for mj in m[1:-1]:
            out["marking"].append(ribbon(track, ds, mj + hw, mj - hw, MARKING_LIFT))
    return out


# --- roadside objects ----------------------------------------------------------------------------------------------
def _templates() -> dict:
    cone = trimesh.creation.cone(radius=1.0, height=1.0, sections=6)
    ball = trimesh.creation.icosphere(subdivisions=0, radius=1.0)
    trunk = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    trunk.apply_translation([0, 0, 0.5])
    block = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    block.apply_translation([0, 0, 0.5])
    return {k: MeshData.from_trimesh(v) for k, v in
            {"cone": cone, "ball": ball, "trunk": trunk, "block": block}.items()}


def _clear_of_road(track: Track, x, y, clearance: float) -> np.ndarray:
    """True where a point is more than `clearance` [m] beyond the road edge of every part of the loop."""
    _, d = track.frenet(x, y)
    return np.abs(d) > track.half_width + clearance


def _roadside(track: Track, rng: np.random.Generator, s0: float, s1: float, style: dict) -> dict:
    """The objects and grass patches beside the road between s0 and s1, by material, drawn from `rng` in a fixed
    order (trees, poles, buildings, guard rails, patches): the same track, style and draws give the same scene."""
    out: dict = {}
    edge = track.half_width + VERGE_WIDTH
    _trees(out, track, rng, s0, s1, style, edge)
    _poles(out, track, s0, s1, style, edge)
    _buildings(out, track, rng, s0, s1, style, edge)
    _guard_rails(out, track, s0, s1, style, edge)
    _grass_patches(out, track, rng, s0, s1, style, edge)
    return out


def _trees(out: dict, track: Track, rng: np.random.Generator, s0: float, s1: float, style: dict,
           edge: float) -> None:
    """Trees on both sides: a trunk and a conical or round crown."""
    tpl = style["templates"]
    n = rng.poisson(style["tree_density"] * (s1 - s0) * 2)
    if n:
        ts = rng.uniform(s0, s1, n)
        side = rng.choice([-1.0, 1.0], n)
        off = side * (edge + rng.uniform(3.0, 35.0, n))
        x, y, h = track.pose(ts, off)
        keep = _clear_of_road(track, x, y, VERGE_WIDTH + 2.5)
        for xi, yi, hi in zip(x[keep], y[keep], h[keep]):
            height = rng.uniform(5.0, 10.0)
            trunk_h = rng.uniform(1.2, 2.5)
            out.setdefault("trunk", []).append(tpl["trunk"].transformed(xi, yi, hi, (0.35, 0.35, trunk_h)))
            if rng.uniform() < 0.5:
                r = height * rng.uniform(0.22, 0.32)
                crown = tpl["cone"].transformed(xi, yi, hi, (r, r, height - trunk_h))
                crown.vertices[:, 2] += trunk_h * 0.7  # the cone's base sits at z = 0
                out.setdefault("foliage_a", []).append(crown)
            else:
                r = rng.uniform(1.8, 3.0)
                crown = tpl["ball"].transformed(xi, yi, hi, (r, r, r * 1.1))
                crown.vertices[:, 2] += trunk_h + r
                out.setdefault("foliage_b", []).append(crown)


def _poles(out: dict, track: Track, s0: float, s1: float, style: dict, edge: float) -> None:
    """Light poles along one side at a fixed spacing: strong motion cues at low cost."""
    if style["poles"]:
        first = math.ceil(s0 / 50.0) * 50.0
        for a in np.arange(first, s1, 50.0):
            x, y, h = track.pose(a, style["pole_side"] * (edge + 0.8))   # as light_poles says
            out.setdefault("pole", []).append(style["templates"]["trunk"].transformed(x, y, h, (0.22, 0.22, 8.0)))


def _buildings(out: dict, track: Track, rng: np.random.Generator, s0: float, s1: float, style: dict,
               edge: float) -> None:
    """Buildings, now and then, well back from the road."""
    if rng.uniform() < style["building_rate"]:
        for _ in range(int(rng.integers(1, 4))):
            a = rng.uniform(s0, s1)
            side = rng.choice([-1.0, 1.0])
            w, dpt, ht = rng.uniform(10, 30), rng.uniform(10, 25), rng.uniform(6, 25)
            off = side * (edge + rng.uniform(20.0, 60.0) + dpt / 2)
            x, y, h = track.pose(a, off)
            corners_ok = _clear_of_road(track, x + np.array([-1, 1, 1, -1]) * w, y + np.array([-1, -1, 1, 1]) * w,
                                        VERGE_WIDTH + 8.0)
            if corners_ok.all():
                mat = ("building_a", "building_b", "building_c")[int(rng.integers(0, 3))]
                out.setdefault(mat, []).append(style["templates"]["block"].transformed(x, y, h, (w, dpt, ht)))


def _guard_rails(out: dict, track: Track, s0: float, s1: float, style: dict, edge: float) -> None:
    """Guard rails on the outside of bends."""
    if style["barriers"]:
        for seg, start in zip(track.segments, track.starts):
            a, b = max(s0, start), min(s1, start + seg.length)
            if seg.kind == "arc" and b > a:
                outer = -1.0 if seg.curvature > 0 else 1.0
                out.setdefault("barrier", []).append(
                    wall(track, road_samples(track, a, b), outer * (edge + 0.4), 0.8))


def _grass_patches(out: dict, track: Track, rng: np.random.Generator, s0: float, s1: float, style: dict,
                   edge: float) -> None:
    """Grass patches: ground texture that moves past the camera."""
    n = rng.poisson(style["patch_density"] * (s1 - s0))
    for _ in range(n):
        a = rng.uniform(s0, s1 - 4.0)
        side = rng.choice([-1.0, 1.0])
        d0 = side * (edge + rng.uniform(0.5, 12.0))
        width = rng.uniform(1.0, 4.0)
        ss = np.linspace(a, a + rng.uniform(3.0, 10.0), 3)
        patch = ribbon(track, ss, max(d0, d0 + side * width), min(d0, d0 + side * width), 0.0)
        out.setdefault("patch_dark" if rng.uniform() < 0.5 else "patch_light", []).append(patch)


def _style(rng: np.random.Generator) -> dict:
    """The roadside's style, the first draws of the scenery's stream."""
    return {"tree_density": rng.uniform(0.03, 0.08), "poles": rng.uniform() < 0.7,
            "pole_side": float(rng.choice([-1.0, 1.0])), "building_rate": rng.uniform(0.1, 0.4),
            "barriers": rng.uniform() < 0.6, "patch_density": rng.uniform(0.1, 0.3)}


def light_poles(track: Track, seed: int) -> tuple[np.ndarray, float]:
    """Where build_scenery puts light poles along the track for `seed` (none on some seeds): their s [m] and their
    lateral offset d [m] (one side of the road)."""
    style = _style(np.random.default_rng([int(seed), 0x5CE7E]))
    s = np.arange(0.0, track.length, 50.0) if style["poles"] else np.zeros(0)
    return s, style["pole_side"] * (track.half_width + VERGE_WIDTH + 0.8)


def build_scenery(track: Track, seed: int) -> list[Chunk]:
    """Static geometry of the whole loop, cut into chunks along s. Same track and seed, same scene."""
    rng = np.random.default_rng([int(seed), 0x5CE7E])
    style = {"templates": _templates(), **_style(rng)}
    n = max(1, int(round(track.length / CHUNK_LENGTH)))
    edges = np.linspace(0.0, track.length, n + 1)
    chunks = []
    for s0, s1 in zip(edges[:-1], edges[1:]):
        ground = _road_polygons(track, s0, s1)
        objects: dict = {}
        for mat, items in _roadside(track, rng, s0, s1, style).items():
            (ground if mat in GROUND_MATERIALS else objects).setdefault(mat, []).extend(items)
        objects = {mat: MeshData.concat(ms) for mat, ms in objects.items()}
        xy = np.vstack([p[:, :2] for ps in ground.values() for p in ps] +
                       [m.vertices[:, :2] for m in objects.values()])
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        chunks.append(Chunk((lo + hi) / 2, float(np.linalg.norm(hi - lo) / 2), ground, objects))
    return chunks
