"""The generalisation protocol (docs/generalisation.md): does a driver read the road, or this renderer's look and
these tracks? The named conditions split into training and new ones, the tracks (presets and procedural seeds) into
training and new ones, traffic into empty, regular and dense; every combination is a cell, a small suite of routes
driven in the cell's conditions, and each model gets a driving score, a success rate and
collisions and off-road events per km per cell (as CARLA's NoCrash reports success per weather, town and traffic).

The protocol file (assets/protocols/generalisation.json is the shipped one):

{"name": str, "description": str (optional),
 "generator": {"seed", "new_conditions", "new_presets", "routes", "seconds"} (optional: how draw_protocol drew it),
 "conditions": {"training": [names], "new": [names]},      named conditions (docs/conditions.md), apart
 "tracks": {"training": [tracks], "new": [tracks]},        presets or procedural:SEED, apart
 "traffic": {"empty": D, "regular": D, "dense": D},        AI cars per km of lane (at most what a track holds)
 "routes": {"training": [route], "new": [route]},          {"name", "track", "lanes", "seed", "start_lane"}
 "seconds": simulated seconds of every route}

A route of split S drives one of S's tracks; a cell (conditions C, tracks S, traffic T) drives every route of S with
T's cars once in each of C's conditions (as CARLA's benchmarks drive every route in every weather of a split). A
file is checked whole before anything is driven: unknown keys, an unknown condition, a split that is empty or shares
a name with the other, a route on a track outside its split: one line naming the file and the field, exit status 2.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from assets import ASSETS_DIR
from core.conditions import CONDITIONS, SEEDED
from core.inputs import check_keys, number, read_bytes, read_json, show, show_path
from drivestudio.worlds.highway.benchmark.suite import (
    MAX_SECONDS,
    MIN_SECONDS,
    NAME,
    Suite,
    SuiteError,
    parse_suite,
    shipped_or_file,
)
from sim.track import MAX_LANES, TrackError, load_track
from sim.track.library import preset_names

PROTOCOLS_DIR = ASSETS_DIR / "protocols"
SPLITS = ("training", "new")
TRAFFIC = ("empty", "regular", "dense")
PROTOCOL_KEYS = ("name", "description", "generator", "conditions", "tracks", "traffic", "routes", "seconds")
GENERATOR_KEYS = ("seed", "new_conditions", "new_presets", "routes", "seconds")
ROUTE_KEYS = ("name", "track", "lanes", "seed", "start_lane")
DENSITY = {"empty": 0.0, "regular": 4.0, "dense": 12.0}   # [cars per km of lane] the drawn protocol's traffic
MAX_DENSITY = 50.0            # [cars per km of lane] one car per 20 m (sim/highway/sumo_traffic.py MIN_SPACING)
MAX_ROUTES_PER_SPLIT = 20
NAMED = tuple(c for c in CONDITIONS if c != SEEDED)
TRAINING_PLAN_TRACKS = 3      # generate's default plans drive procedural:1000k + 0..2 (draw.py)


class ProtocolError(SuiteError):
    """A protocol that cannot be run: one line naming the file and the field (a UsageError: exit status 2)."""


@dataclass(frozen=True)
class Cell:
    """One cell of the protocol: its split's routes, each driven once in every condition of its conditions' split
    (a suite of routes x conditions, each route named `CELL.ROUTE.CONDITION`)."""
    conditions: str    # "training" or "new"
    tracks: str        # "training" or "new"
    traffic: str       # "empty", "regular" or "dense"
    condition: str     # the conditions' names, comma-separated
    suite: Suite

    def by_condition(self) -> list[tuple[str, Suite]]:
        """The cell's suite cut into one suite per condition, in the split's order."""
        return [(c, self.suite.select([r.name for r in self.suite.routes if r.name.endswith("." + c)]))
                for c in self.condition.split(",")]

    @property
    def name(self) -> str:
        return cell_name(self.conditions, self.tracks, self.traffic)


def cell_name(conditions: str, tracks: str, traffic: str) -> str:
    """A cell's name, also the prefix of its routes' names: `new-cond.train-tracks.dense`."""
    short = {"training": "train", "new": "new"}
    return f"{short[conditions]}-cond.{short[tracks]}-tracks.{traffic}"


@dataclass(frozen=True)
class Protocol:
    name: str
    description: str
    conditions: dict[str, tuple[str, ...]]
    tracks: dict[str, tuple[str, ...]]
    traffic: dict[str, float]
    seconds: float
    cells: tuple[Cell, ...]
    path: str
    sha256: str
    generator: dict | None = None


# --- drawing the shipped protocol ---------------------------------------------------------------------------------
def _procedural(rng: np.random.Generator, training: bool) -> str:
    """A procedural track of a training plan's kind (seed mod 1000 < 3) or of no plan's (the random suites' kind)."""
    while True:
        t = int(rng.integers(3, 1_000_000))
        if (t % 1000 < TRAINING_PLAN_TRACKS) == training:
            return f"procedural:{t}"


def _routes(rng: np.random.Generator, split: str, tracks: list[str], count: int) -> list[dict]:
    """`count` routes of a split, each on the next of its tracks in a drawn order, with a lane count its bends allow."""
    order = [tracks[i] for i in rng.permutation(len(tracks))]
    out = []
    for i in range(count):
        track = order[i % len(order)]
        while True:
            lanes = int(rng.integers(1, 4))   # 1-3 lanes, as the default suite
            try:
                load_track(track, lanes=lanes)
                break
            except TrackError:
                continue
        out.append({"name": f"{split}-{i + 1}", "track": track, "lanes": lanes,
                    "seed": int(rng.integers(0, 2**31)), "start_lane": int(rng.integers(0, lanes))})
    return out


def draw_protocol(seed: int, new_conditions: int = 2, new_presets: int = 3, routes: int = 3,
                  seconds: float = 120.0) -> dict:
    """The protocol drawn from `seed`, as the file holds it. One generator, numpy.random.default_rng(seed), draws in
    this order: a permutation of the named conditions (the first `new_conditions` new, the rest training); a
    permutation of the presets (the first `new_presets` new); a procedural track of a training plan's kind and one
    of no plan's; then each split's routes (track order, and per route lanes, seed and start lane)."""
    rng = np.random.default_rng(seed)
    perm = [NAMED[i] for i in rng.permutation(len(NAMED))]
    conditions = {"training": sorted(perm[new_conditions:], key=CONDITIONS.index),
                  "new": sorted(perm[:new_conditions], key=CONDITIONS.index)}
    presets = preset_names()
    shuffled = [presets[i] for i in rng.permutation(len(presets))]
    tracks = {"training": sorted(shuffled[new_presets:]) + [_procedural(rng, True)],
              "new": sorted(shuffled[:new_presets]) + [_procedural(rng, False)]}
    return {"name": "generalisation",
            "description": f"drawn by draw_protocol({seed}) (docs/benchmark.md, the generalisation protocol): "
                           f"{len(NAMED) - new_conditions} training and {new_conditions} new conditions, "
                           f"{len(presets) - new_presets} training and {new_presets} new presets and a procedural "
                           f"track each, empty, regular and dense traffic; nobody chose a split.",
            "generator": {"seed": seed, "new_conditions": new_conditions, "new_presets": new_presets,
                          "routes": routes, "seconds": seconds},
            "conditions": conditions, "tracks": tracks, "traffic": dict(DENSITY),
            "routes": {s: _routes(rng, s, tracks[s], routes) for s in SPLITS}, "seconds": seconds}


# --- reading a protocol file --------------------------------------------------------------------------------------
def _split(obj: dict, key: str, check) -> dict[str, tuple[str, ...]]:
    v = obj.get(key)
    if not isinstance(v, dict):
        raise ProtocolError(f"'{key}' must be an object {{\"training\": [...], \"new\": [...]}}, got {show(v)}")
    check_keys(v, SPLITS, key, ProtocolError)
    out = {}
    for s in SPLITS:
        names = v.get(s)
        if not isinstance(names, list) or not names or len(names) > 50 or not all(isinstance(n, str) for n in names):
            raise ProtocolError(f"{key}: '{s}' must be a list of 1 to 50 names, got {show(names)}")
        for n in names:
            check(n, f"{key}: {s}")
        if len(set(names)) != len(names):
            raise ProtocolError(f"{key}: '{s}' names {show(names)} more than once")
        out[s] = tuple(names)
    shared = sorted(set(out["training"]) & set(out["new"]))
    if shared:
        raise ProtocolError(f"{key}: {', '.join(shared)} is both a training and a new one; the splits must be apart")
    return out


def _condition(name: str, where: str) -> None:
    if name not in NAMED:
        raise ProtocolError(f"{where}: unknown condition {show(name)} (choose from {', '.join(NAMED)})")


def _track(name: str, where: str) -> None:
    try:
        load_track(name)
    except TrackError as e:
        raise ProtocolError(f"{where}: track {show(name, 60)}: {e}") from None


def _traffic(obj: dict) -> dict[str, float]:
    v = obj.get("traffic")
    if not isinstance(v, dict):
        raise ProtocolError(f"'traffic' must be an object {{\"empty\": D, \"regular\": D, \"dense\": D}} of cars per "
                            f"km of lane, got {show(v)}")
    check_keys(v, TRAFFIC, "traffic", ProtocolError)
    return {t: number(v, t, "traffic", lo=0.0, hi=MAX_DENSITY, unit="cars per km of lane", error=ProtocolError)
            for t in TRAFFIC}


def _cars(route: dict, density: float) -> int:
    """The route's AI cars at `density` per km of lane, at most what its track holds (the suite's own check)."""
    from sim.highway.sumo_traffic import MIN_SPACING  # lazy: the SUMO traffic module (trimesh, PIL)
    track = load_track(route["track"], lanes=route["lanes"])
    lane_km = track.lanes * track.length / 1000.0
    return min(int(round(density * lane_km)), int(track.lanes * track.length / MIN_SPACING))


def _cells(obj: dict, source: str, conditions, tracks, traffic, seconds) -> tuple[Cell, ...]:
    routes = obj.get("routes")
    if not isinstance(routes, dict):
        raise ProtocolError(f"'routes' must be an object {{\"training\": [...], \"new\": [...]}}, got {show(routes)}")
    check_keys(routes, SPLITS, "routes", ProtocolError)
    cells = []
    for s in SPLITS:
        rows = routes.get(s)
        if not isinstance(rows, list) or not rows or len(rows) > MAX_ROUTES_PER_SPLIT:
            raise ProtocolError(f"routes: '{s}' must be a list of 1 to {MAX_ROUTES_PER_SPLIT} routes, got {show(rows)}")
        for i, r in enumerate(rows):
            where = f"routes: {s} {i}"
            if not isinstance(r, dict):
                raise ProtocolError(f"{where}: expected an object with {', '.join(ROUTE_KEYS)}, got {show(r)}")
            check_keys(r, ROUTE_KEYS, where, ProtocolError, kind="a route")
            if r.get("track") not in tracks[s]:
                raise ProtocolError(f"{where}: track {show(r.get('track'), 60)} is not one of the {s} tracks")
            number(r, "lanes", where, lo=1, hi=MAX_LANES, integer=True, error=ProtocolError)
        for t in TRAFFIC:
            for c in SPLITS:
                name = cell_name(c, s, t)
                named = [{**r, "name": f"{name}.{r.get('name')}.{condition}", "seconds": seconds,
                          "cars": _cars(r, traffic[t])} for r in rows for condition in conditions[c]]
                suite = parse_suite({"name": name, "routes": named}, source, Path("."))
                cells.append(Cell(c, s, t, ",".join(conditions[c]), suite))
    order = {(c, s, t): i for i, (c, s, t) in enumerate((c, s, t) for c in SPLITS for s in SPLITS for t in TRAFFIC)}
    return tuple(sorted(cells, key=lambda cell: order[(cell.conditions, cell.tracks, cell.traffic)]))


def parse_protocol(obj, source: str, sha256: str = "") -> Protocol:
    try:
        if not isinstance(obj, dict):
            raise ProtocolError(f"a protocol must be a JSON object with {', '.join(PROTOCOL_KEYS)}, got {show(obj)}")
        check_keys(obj, PROTOCOL_KEYS, "protocol", ProtocolError)
        name = obj.get("name")
        if not isinstance(name, str) or not NAME.fullmatch(name):
            raise ProtocolError(f"'name' must be 1 to 64 letters, digits, '_', '.', '+' or '-', got {show(name)}")
        description = obj.get("description", "-")
        if not isinstance(description, str) or len(description) > 2000:
            raise ProtocolError(f"'description' must be a line of at most 2000 characters, got {show(description)}")
        generator = obj.get("generator")
        if generator is not None:
            if not isinstance(generator, dict):
                raise ProtocolError(f"'generator' must be an object with {', '.join(GENERATOR_KEYS)}")
            check_keys(generator, GENERATOR_KEYS, "generator", ProtocolError)
        conditions = _split(obj, "conditions", _condition)
        tracks = _split(obj, "tracks", _track)
        traffic = _traffic(obj)
        seconds = number(obj, "seconds", "protocol", lo=MIN_SECONDS, hi=MAX_SECONDS, unit="s", error=ProtocolError)
        cells = _cells(obj, source, conditions, tracks, traffic, seconds)
    except SuiteError as e:
        raise ProtocolError(f"{source}: {str(e).removeprefix(source + ': ')}") from None
    return Protocol(name, description, conditions, tracks, traffic, seconds, cells, source, sha256, generator)


def load_protocol(ref: str) -> Protocol:
    """A shipped protocol by name (assets/protocols/NAME.json) or a protocol file, checked whole."""
    path = shipped_or_file(ref, PROTOCOLS_DIR, "--protocol", "protocol", ProtocolError)
    obj = read_json(path, "protocol", error=ProtocolError)
    sha256 = hashlib.sha256(read_bytes(path, "protocol", error=ProtocolError)).hexdigest()
    return parse_protocol(obj, show_path(path), sha256)


def protocol_text(seed: int) -> str:
    """The protocol file drawn from `seed`, one route per line (assets/protocols/generalisation.json is seed 49's):
    `python -m drivestudio.worlds.highway.benchmark.protocol 49 > FILE`."""
    d = draw_protocol(seed)
    head = {k: v for k, v in d.items() if k != "routes"}
    lines = ["{"] + [f"  {json.dumps(k)}: {json.dumps(v)}," for k, v in head.items()] + ['  "routes": {']
    for i, s in enumerate(SPLITS):
        rows = ",\n".join(f"      {json.dumps(r)}" for r in d["routes"][s])
        lines.append(f'    "{s}": [\n{rows}\n    ]' + ("," if i == 0 else ""))
    return "\n".join(lines + ["  }", "}", ""])


if __name__ == "__main__":
    import sys
    sys.stdout.write(protocol_text(int(sys.argv[1])))
