"""Draw docs/img/conditions-highway.png and docs/img/conditions-sidewalk.png: the same scene in every named condition
(docs/conditions.md), drawn by renderer numba (the highway's, with the rear-view mirror) and by the sidewalk's
painter (its left camera).

    .venv/bin/python docs/figures/conditions_figures.py [--seed 0] [--out docs/img]

The highway's scene: `procedural:3` (3 lanes), seed 0 (its road has light poles: street lamps at night), the host
in the middle lane where the road heads closest to seed 0's low sun (its glare in view), five cars ahead and one
behind (in the mirror). The sidewalk's: the park preset, seed 0, following the lead car a few metres ahead.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from core.conditions import CONDITIONS  # noqa: E402
from sim.highway.conditions import draw_condition  # noqa: E402
from sim.highway.scenario import scenario_from_dict  # noqa: E402
from sim.highway.world import World, WorldConfig  # noqa: E402
from sim.sidewalk.config import SidewalkConfig  # noqa: E402
from sim.sidewalk.world import SidewalkWorld  # noqa: E402
from sim.track import load_track  # noqa: E402

TRACK = "procedural:3"


def towards_the_sun(seed: int) -> float:
    """The s [m] of the track where its heading is closest to the low sun's azimuth, a little to the left of it."""
    track = load_track(TRACK, lanes=3)
    sun = draw_condition("low_sun", seed).sun_azimuth
    s = np.arange(0.0, track.length, 2.0)
    heading = track.pose(s, np.zeros_like(s))[2]
    off = np.abs((heading - sun + 0.25 + np.pi) % (2 * np.pi) - np.pi)
    return float(s[int(np.argmin(off))])


def highway_tiles(seed: int) -> list[tuple[str, np.ndarray]]:
    s0 = towards_the_sun(seed)
    cars = [{"s": s0 + a, "d": d, "speed": 20.0} for a, d in ((9.0, 3.6), (16.0, 0.0), (30.0, -3.6), (45.0, 0.0),
                                                            (70.0, 3.6))]
    cars.append({"s": s0 - 11.0, "d": 3.6, "speed": 20.0})
    scenario = scenario_from_dict({"track": TRACK, "lanes": 3, "seed": seed,
                                   "ego": {"s": s0, "d": 0.0, "speed": 20.0}, "cars": cars})
    tiles = []
    for name in CONDITIONS:
        with World(WorldConfig(cars=0, condition=name, mirror=True), scenario=scenario) as world:
            tiles.append((name, world.observe().frame))
    return tiles


def sidewalk_tiles(seed: int) -> list[tuple[str, np.ndarray]]:
    tiles = []
    for name in CONDITIONS:
        with SidewalkWorld(SidewalkConfig(path="park", seed=seed, mode="follow", obstacles=2.0,
                                          condition=name)) as world:
            for _ in range(20):
                obs = world.step([0.5, 0.62])
            tiles.append((name, obs.frames[0]))
    return tiles


def grid(tiles: list[tuple[str, np.ndarray]], columns: int = 4) -> np.ndarray:
    """The tiles in rows of `columns`, each named at its bottom left, the last row filled with black."""
    h, w = tiles[0][1].shape[:2]
    named = []
    for name, img in tiles:
        img = img.copy()
        cv2.rectangle(img, (0, h - 18), (8 + 9 * len(name), h), (0, 0, 0), -1)
        cv2.putText(img, name, (4, h - 5), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
        named.append(img)
    named += [np.zeros_like(named[0])] * (-len(named) % columns)
    rows = [np.hstack(named[i:i + columns]) for i in range(0, len(named), columns)]
    return np.vstack(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "img")
    args = ap.parse_args()
    for name, tiles in (("highway", highway_tiles(args.seed)), ("sidewalk", sidewalk_tiles(args.seed))):
        path = args.out / f"conditions-{name}.png"
        cv2.imwrite(str(path), grid(tiles)[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 9])
        print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KB)")


if __name__ == "__main__":
    main()
