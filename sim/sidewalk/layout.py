"""What stands where along a path: the borders (hedges and rows of bushes beside the path, with gaps), the
obstacles on the path, the trees and lamp posts beyond, and where the car starts. A pure function of the path,
the seed and the obstacle option, shared by the truth (which needs only geometry) and the scenery (which draws it).

Obstacles come from a density (per 100 m of path, placed by the seed) or from an obstacle file
(docs/sidewalk.md, "Obstacle files"):

    {"obstacles": [{"kind": "cone", "s": 12.0, "d": 0.4}, {"kind": "bench", "s": 40.0, "d": -0.6, "yaw_deg": 0}]}

s [m] along the path, d [m] from its centreline (positive left), yaw_deg the obstacle's turn from the path's
direction. Every obstacle must stand on the path and leave a passage of at least PASSAGE beside it, and
obstacles must be MIN_SPACING apart along the path, so that the experts can always drive round them.
"""
from __future__ import annotations

import bisect
import math
import numbers
from dataclasses import dataclass, field

import numpy as np

from core.inputs import read_json, show
from sim.sidewalk.car import CAR
from sim.sidewalk.errors import PathError
from sim.sidewalk.paths import SidewalkPath

# kind: (length along its own axis, width, height) [m]; a bench and a parked bike stand along the path, a
# pedestrian faces across it
OBSTACLE_SIZES = {"cone": (0.28, 0.28, 0.45), "post": (0.12, 0.12, 0.85), "bench": (1.4, 0.5, 0.8),
                  "bike": (1.7, 0.45, 1.0), "pedestrian": (0.3, 0.5, 1.7)}
OBSTACLE_KINDS = tuple(OBSTACLE_SIZES)
PASSAGE = CAR.width + 0.5           # [m] free width an obstacle must leave beside it, on one side at least
MIN_SPACING = 8.0                   # [m] between obstacles' centres along the path
START_CLEAR = (3.0, 10.0)           # [m] no obstacle this far behind / ahead of the start
MAX_DENSITY = 12.0                  # obstacles per 100 m
MAX_OBSTACLES = 200                 # in a file
BORDER_KINDS = ("hedge", "bushes")
BORDER_FACE = (0.12, 0.35)          # [m] beyond the path's edge: where a border's face stands
BORDER_CAP = 5.0                    # [m] border distance where there is none


@dataclass(frozen=True)
class Obstacle:
    kind: str
    s: float                 # [m] centre, along the path
    d: float                 # [m] centre, from the centreline
    yaw: float               # [rad] its axis, relative to the path tangent
    length: float            # [m] along its own axis
    width: float             # [m]
    height: float            # [m]
    x: float = 0.0           # [m] world position of its centre
    y: float = 0.0
    world_yaw: float = 0.0   # [rad]

    @property
    def along(self) -> float:
        """[m] extent along the path (its footprint's projection on the tangent)."""
        return abs(self.length * math.cos(self.yaw)) + abs(self.width * math.sin(self.yaw))

    @property
    def across(self) -> float:
        """[m] extent across the path."""
        return abs(self.length * math.sin(self.yaw)) + abs(self.width * math.cos(self.yaw))


@dataclass
class Border:
    """Stretches of hedge or bushes along one side: stretch i covers s in [starts[i], ends[i]) and its face (the
    line every hedge face and bush of it touches) stands |face[i]| from the centreline."""

    side: float                        # +1 left, -1 right
    starts: list = field(default_factory=list)
    ends: list = field(default_factory=list)
    face: list = field(default_factory=list)      # [m] signed offset d of the face
    kinds: list = field(default_factory=list)
    heights: list = field(default_factory=list)   # [m]
    depths: list = field(default_factory=list)    # [m] from the face outwards

    def at(self, s: float) -> int | None:
        """Index of the stretch beside s, or None in a gap."""
        i = bisect.bisect_right(self.starts, s) - 1
        return i if i >= 0 and s < self.ends[i] else None


@dataclass
class Tree:
    x: float
    y: float
    height: float            # [m]
    trunk: float             # [m] trunk radius
    crown: float             # [m] crown radius
    conifer: bool


@dataclass
class Layout:
    path: SidewalkPath
    seed: int
    start_s: float
    borders: tuple[Border, Border]            # left, right
    obstacles: list[Obstacle]
    trees: list[Tree]
    lamps: list[tuple[float, float]]          # (x, y) [m] of lamp posts
    obstacle_source: str = ""                 # "density N" or the obstacle file

    def __post_init__(self):
        order = sorted(range(len(self.obstacles)), key=lambda i: self.obstacles[i].s)
        self.obstacles = [self.obstacles[i] for i in order]
        self.obstacle_s = np.array([o.s for o in self.obstacles])
        self.obstacle_d = np.array([o.d for o in self.obstacles])
        self.obstacle_along = np.array([o.along for o in self.obstacles])
        self.obstacle_across = np.array([o.across for o in self.obstacles])
        self.obstacle_boxes = np.array([(o.x, o.y, o.world_yaw, o.length, o.width) for o in self.obstacles]
                                       ).reshape(-1, 5)
        self.tree_boxes = np.array([(t.x, t.y, 0.0, 2 * t.trunk, 2 * t.trunk) for t in self.trees]).reshape(-1, 5)


# --- obstacles ----------------------------------------------------------------------------------------------------
def make_obstacle(path: SidewalkPath, kind: str, s: float, d: float, yaw: float) -> Obstacle:
    length, width, height = OBSTACLE_SIZES[kind]
    x, y, h = path.track.pose(s, d)
    return Obstacle(kind, float(s), float(d), float(yaw), length, width, height, x, y, h + yaw)


def _check_obstacles(path: SidewalkPath, obstacles: list[Obstacle], where: str) -> None:
    hw = path.half_width
    for i, o in enumerate(obstacles):
        left = hw - (o.d + o.across / 2)     # free width beside it on the left
        right = (o.d - o.across / 2) + hw
        if abs(o.d) > hw:
            raise PathError(f"{where}: obstacle {i} ({o.kind}) stands off the path (|d| = {abs(o.d):.2f} m; the "
                            f"path is {path.width:g} m wide)")
        if max(left, right) < PASSAGE:
            raise PathError(f"{where}: obstacle {i} ({o.kind} at s = {o.s:.1f} m) blocks the path: it leaves "
                            f"{max(left, right, 0.0):.2f} m beside it, at least {PASSAGE:.2f} m are needed")
    s = sorted(o.s for o in obstacles)
    for a, b in zip(s, s[1:] + ([s[0] + path.length] if len(s) > 1 else [])):
        if b - a < MIN_SPACING:
            raise PathError(f"{where}: obstacles at s = {a:.1f} m and s = {b % path.length:.1f} m are closer than "
                            f"{MIN_SPACING:g} m along the path")


def obstacles_from_file(path: SidewalkPath, file, start_s: float | None = None) -> list[Obstacle]:
    """The obstacles of an obstacle file, checked against the path (one PathError line naming the file)."""
    data = read_json(file, "obstacle", error=PathError)
    where = str(file)
    if not isinstance(data, dict) or set(data) != {"obstacles"} or not isinstance(data["obstacles"], list):
        raise PathError(f"{where}: an obstacle file is one JSON object {{\"obstacles\": [...]}}")
    items = data["obstacles"]
    if len(items) > MAX_OBSTACLES:
        raise PathError(f"{where}: {len(items)} obstacles; a file may list at most {MAX_OBSTACLES}")
    out = []
    for i, item in enumerate(items):
        at = f"{where}: obstacle {i}"
        if not isinstance(item, dict):
            raise PathError(f"{at}: expected an object with kind, s and d")
        unknown = set(item) - {"kind", "s", "d", "yaw_deg"}
        if unknown:
            raise PathError(f"{at}: unknown field {sorted(unknown)[0]!r}; the fields are kind, s, d, yaw_deg")
        kind = item.get("kind")
        if not isinstance(kind, str) or kind not in OBSTACLE_SIZES:   # (a list is unhashable: no dict lookup)
            raise PathError(f"{at}: 'kind' must be one of {', '.join(OBSTACLE_KINDS)}, got {show(kind)}")
        values = {}
        for key, lo, hi, default in (("s", 0.0, path.length, None), ("d", -path.half_width, path.half_width, None),
                                     ("yaw_deg", -180.0, 180.0, 0.0)):
            v = item.get(key, default)
            if v is None:
                raise PathError(f"{at}: missing '{key}'")
            if not isinstance(v, numbers.Real) or isinstance(v, bool) or not math.isfinite(v):
                raise PathError(f"{at}: '{key}' must be a finite number, got {v!r}")
            if not lo <= float(v) <= hi:
                raise PathError(f"{at}: '{key}' must be from {lo:g} to {hi:g}, got {v:g}")
            values[key] = float(v)
        out.append(make_obstacle(path, item["kind"], values["s"] % path.length, values["d"],
                                 math.radians(values["yaw_deg"])))
    _check_obstacles(path, out, where)
    return out


def place_obstacles(path: SidewalkPath, density: float, rng: np.random.Generator, start_s: float) -> list[Obstacle]:
    """About density obstacles per 100 m, at least MIN_SPACING apart, each leaving a passage on one side."""
    n = int(round(density * path.length / 100.0))
    hw = path.half_width
    out: list[Obstacle] = []
    tries = 0
    while len(out) < n and tries < 50 * n:
        tries += 1
        s = float(rng.uniform(0.0, path.length))
        ahead = path.track.gap(start_s, s)
        if -START_CLEAR[0] < ahead < START_CLEAR[1]:
            continue
        if any(abs(path.track.gap(o.s, s)) < MIN_SPACING for o in out):
            continue
        kind = OBSTACLE_KINDS[int(rng.integers(len(OBSTACLE_KINDS)))]
        length, width, _ = OBSTACLE_SIZES[kind]
        yaw = {"bench": 0.0, "bike": float(rng.uniform(-0.25, 0.25)),
               "pedestrian": float(rng.uniform(-0.6, 0.6))}.get(kind, float(rng.uniform(-math.pi, math.pi)))
        across = abs(length * math.sin(yaw)) + abs(width * math.cos(yaw))
        # the centre's range that keeps it on the path and a passage free on one side
        lo, hi = -hw + across / 2, hw - across / 2
        room = 2 * hw - across - PASSAGE       # how far it may stand from the edge it leans on
        if room < 0 or hi < lo:
            continue
        side = 1.0 if rng.uniform() < 0.5 else -1.0
        inset = float(rng.uniform(0.0, min(room, 2 * hw)))
        d = hi - inset if side > 0 else lo + inset
        out.append(make_obstacle(path, kind, s, float(np.clip(d, lo, hi)), yaw))
    return out


# --- borders, trees, lamps -----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Style:
    """How a path's surroundings are drawn; a pair is the (low, high) of a uniform draw."""

    zone: tuple[float, float]     # [m] length of a bordered zone
    open: tuple[float, float]     # [m] length of an open zone (no border on either side) between bordered ones
    border: tuple[float, float]   # [m] a border's stretch inside a bordered zone
    gap: tuple[float, float]      # [m] a gap between two stretches
    hedge: float                  # the odds that a stretch is a hedge (else bushes)
    trees: float                  # trees per metre per side
    lamps: float                  # [m] lamp post spacing (0: none)


STYLE = {
    "sidewalk": Style(zone=(15.0, 45.0), open=(5.0, 16.0), border=(6.0, 25.0), gap=(1.5, 6.0), hedge=0.8,
                      trees=0.06, lamps=20.0),
    "park": Style(zone=(12.0, 40.0), open=(5.0, 18.0), border=(5.0, 20.0), gap=(1.5, 8.0), hedge=0.45,
                  trees=0.12, lamps=28.0),
    "forest": Style(zone=(10.0, 35.0), open=(4.0, 14.0), border=(4.0, 16.0), gap=(1.5, 6.0), hedge=0.0,
                    trees=0.45, lamps=0.0),
}


def make_borders(path: SidewalkPath, rng: np.random.Generator) -> tuple[Border, Border]:
    """Borders on both sides: the loop alternates bordered zones, where each side is hedged or lined with bushes
    over stretches with short gaps, and open zones with no border on either side (where furtive mode speeds
    up). No stretch runs over the seam at s = 0."""
    st = STYLE[path.style]
    zones = []
    s = float(rng.uniform(0.0, 8.0))
    while s < path.length - 5.0:
        end = min(s + float(rng.uniform(*st.zone)), path.length - 2.0)
        zones.append((s, end))
        s = end + float(rng.uniform(*st.open))
    hw = path.half_width
    out = []
    for side in (1.0, -1.0):
        b = Border(side)
        for z0, z1 in zones:
            s = z0 + float(rng.uniform(0.0, 2.0))
            while True:
                end = min(s + float(rng.uniform(*st.border)), z1)
                if end - s < 2.5:
                    break
                kind = "hedge" if rng.uniform() < st.hedge else "bushes"
                b.starts.append(s)
                b.ends.append(end)
                b.face.append(side * (hw + float(rng.uniform(*BORDER_FACE))))
                b.kinds.append(kind)
                b.heights.append(float(rng.uniform(0.6, 1.2) if kind == "hedge" else rng.uniform(0.45, 0.9)))
                b.depths.append(float(rng.uniform(0.5, 0.9) if kind == "hedge" else rng.uniform(0.6, 1.0)))
                s = end + float(rng.uniform(*st.gap))
        out.append(b)
    return out[0], out[1]


def _clear_of_path(path: SidewalkPath, x, y, clearance: float) -> np.ndarray:
    """True where points are more than `clearance` [m] beyond the path's edge from every part of the loop."""
    _, d = path.track.frenet(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
    return np.abs(d) > path.half_width + clearance


def make_trees(path: SidewalkPath, rng: np.random.Generator) -> list[Tree]:
    st = STYLE[path.style]
    hw = path.half_width
    n = rng.poisson(st.trees * path.length * 2)
    s = rng.uniform(0.0, path.length, n)
    side = np.where(rng.uniform(size=n) < 0.5, 1.0, -1.0)
    near = 1.5 if path.style != "forest" else 1.4
    off = side * (hw + near + rng.exponential(5.0 if path.style == "forest" else 7.0, n))
    x, y, _ = path.track.pose(s, off)
    keep = _clear_of_path(path, x, y, near - 0.05) if n else np.zeros(0, bool)
    trees = []
    for xi, yi in zip(x[keep], y[keep]):
        conifer = rng.uniform() < (0.6 if path.style == "forest" else 0.25)
        height = float(rng.uniform(4.0, 12.0))
        trees.append(Tree(float(xi), float(yi), height, float(rng.uniform(0.08, 0.22)),
                          float(height * rng.uniform(0.2, 0.3) if conifer else rng.uniform(1.2, 2.6)), conifer))
    return trees


def make_lamps(path: SidewalkPath, rng: np.random.Generator) -> list[tuple[float, float]]:
    spacing = STYLE[path.style].lamps
    if not spacing:
        return []
    side = 1.0 if rng.uniform() < 0.5 else -1.0
    s = np.arange(float(rng.uniform(0.0, spacing)), path.length - 1.0, spacing)
    x, y, _ = path.track.pose(s, side * (path.half_width + 1.45))
    keep = _clear_of_path(path, x, y, 1.3)
    return [(float(a), float(b)) for a, b in zip(x[keep], y[keep])]


def build_layout(path: SidewalkPath, seed: int, obstacles=4.0, start_s: float | None = None) -> Layout:
    """The layout of `path` for `seed`: obstacles is a density (per 100 m), a list of Obstacle, or an obstacle
    file; start_s [m] where the car starts (default: drawn from the seed)."""
    rng = np.random.default_rng([int(seed), 0x1A7])
    drawn_start = float(rng.uniform(0.0, path.length))
    start = drawn_start if start_s is None else float(start_s) % path.length
    borders = make_borders(path, rng)
    orng = np.random.default_rng([int(seed), 0x0B5])
    if isinstance(obstacles, (int, float)) and not isinstance(obstacles, bool):
        if not (math.isfinite(obstacles) and 0.0 <= obstacles <= MAX_DENSITY):
            raise PathError(f"the obstacle density must be from 0 to {MAX_DENSITY:g} per 100 m, got {obstacles}")
        items, source = place_obstacles(path, float(obstacles), orng, start), f"density {obstacles:g}"
    elif isinstance(obstacles, list):
        items, source = list(obstacles), "given"
        _check_obstacles(path, items, "obstacles")
    else:
        items, source = obstacles_from_file(path, obstacles), str(obstacles)
    trng = np.random.default_rng([int(seed), 0x7EE])
    return Layout(path, int(seed), start, borders, items, make_trees(path, trng), make_lamps(path, trng), source)
