"""Suites nobody picked by hand: every route drawn from one generator seed (docs/benchmark.md, "Random suites").

    drivestudio suite --seed 19 --out assets/suites/random.json
    drivestudio suite --seed 20 --routes 10 --out runs/random-20.json

Route i (i = 1 .. routes) of the suite drawn from seed S; one generator, numpy.random.default_rng(S), draws in
this order for each route:

    lanes       uniform integer in [lanes_lo, lanes_hi]
    track       procedural:T, T uniform integer in [3, 1,000,000), drawn again while T mod 1000 < 3 (generate's
                training tracks are procedural:1000k + 0..2) or while the track's bends are too tight for that
                many lanes
    cars        uniform integer in [cars_lo, cars_hi], at most what the track holds (one car per 20 m of lane)
    seed        uniform integer in [0, 2^31): the traffic's and the scenery's
    start_lane  uniform integer in [0, lanes)
    seconds     the same for every route

The file records the generator (`"generator": {"seed": S, ...}`), so that anyone can draw it again and check
that no route was swapped after it was driven (tests/drivestudio/test_benchmark.py does).
"""
from __future__ import annotations

import json

import numpy as np

from sim.track import TrackError, load_track

TRACK_SEEDS = (3, 1_000_000)    # procedural track seeds are drawn from [3, 1e6) ...
TRAINING_TRACKS = 3             # ... but never k * 1000 + 0..2: generate's default plans drive those
LANES = (1, 4)
CARS = (12, 60)
SECONDS = 240.0
ROUTES = 12
MIN_SPACING = 20.0              # [m] of lane per car (sim/highway/sumo_traffic.py MIN_SPACING)


def _track(rng: np.random.Generator, lanes: int):
    while True:
        t = int(rng.integers(*TRACK_SEEDS))
        if t % 1000 < TRAINING_TRACKS:
            continue
        try:
            return t, load_track(f"procedural:{t}", lanes=lanes)
        except TrackError:
            continue    # bends too tight for this many lanes: another track


def draw_routes(seed: int, routes: int = ROUTES, lanes: tuple[int, int] = LANES, cars: tuple[int, int] = CARS,
                seconds: float = SECONDS) -> list[dict]:
    """The routes of the suite drawn from `seed` (the module's docstring gives the rule)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(routes):
        n = int(rng.integers(lanes[0], lanes[1] + 1))
        t, track = _track(rng, n)
        capacity = int(n * track.length / MIN_SPACING)
        k = int(rng.integers(cars[0], min(cars[1], capacity) + 1))
        traffic = int(rng.integers(0, 2**31))
        start = int(rng.integers(0, n))
        out.append({"name": f"r{i + 1:02d}-p{t}-{n}l", "track": f"procedural:{t}", "lanes": n, "cars": k,
                    "seed": traffic, "start_lane": start, "seconds": seconds})
    return out


def generator(seed: int, routes: int = ROUTES, lanes: tuple[int, int] = LANES, cars: tuple[int, int] = CARS,
              seconds: float = SECONDS) -> dict:
    """The `generator` record of a suite file: everything draw_routes needs to draw it again."""
    return {"seed": seed, "routes": routes, "lanes": list(lanes), "cars": list(cars), "seconds": seconds}


def suite_text(name: str, gen: dict) -> str:
    """The suite file, one route per line (as the shipped suites are written)."""
    routes = draw_routes(gen["seed"], gen["routes"], tuple(gen["lanes"]), tuple(gen["cars"]), gen["seconds"])
    description = (f"{gen['routes']} routes drawn from generator seed {gen['seed']} by `drivestudio suite --seed "
                   f"{gen['seed']}` (docs/benchmark.md, random suites): {gen['lanes'][0]}-{gen['lanes'][1]} lanes, "
                   f"{gen['cars'][0]}-{gen['cars'][1]} AI cars, procedural tracks that generate's training plans "
                   f"never drive; nobody chose a route.")
    return "\n".join(["{", f'  "name": {json.dumps(name)},', f'  "description": {json.dumps(description)},',
                      f'  "generator": {json.dumps(gen)},', '  "routes": [',
                      ",\n".join("    " + json.dumps(r) for r in routes), "  ]", "}", ""])
