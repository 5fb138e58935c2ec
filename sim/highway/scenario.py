"""The scenario file format (docs/scenarios.md): a track, the host car and other cars at given places.

{"track": <track object | preset name | "procedural:SEED" | path to a track file>,
 "lanes": N (optional, overrides the track's), "seed": int (optional, scene look),
 "ego": {"s": m, "d": m, "heading": rad, "speed": m/s},
 "cars": [{"s": m, "d": m, "speed": m/s (optional)}, ...]}

d is positive to the left; heading is the host car's yaw relative to the track tangent (counter-clockwise
positive), so angle = -heading. Cars are placed heading along the track.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from core.inputs import InputError, check_keys, number, read_json, show, show_path
from sim.highway.truth import EDGE_OUTSIDE
from sim.highway.vehicle import VehicleState
from sim.track import MAX_LANES, Track, TrackError, load_track

# --- limits of a scenario (docs/scenarios.md, "Limits"); a scenario file is also bounded by read_json's
# MAX_JSON_BYTES and MAX_JSON_DEPTH, and its track by the track limits (docs/tracks.md)
MAX_SEED = 2**32 - 1          # 'seed' is 0 .. 2**32 - 1
MAX_SPEED = 100.0             # [m/s] the host car's and every car's speed is 0 .. 100 m/s (360 km/h)
MAX_HEADING = math.pi         # [rad] the host car's heading relative to the track is -pi .. pi
MAX_CARS = 300                # cars placed by a scenario (as many as SUMO's AI cars may be)
# s must lie within one lap either way (-L .. L, wrapped onto the loop); d on the road or its verges

SCENARIO_KEYS = ("track", "lanes", "seed", "ego", "cars")
EGO_KEYS = ("s", "d", "heading", "speed")
CAR_KEYS = ("s", "d", "speed")


class ScenarioError(InputError):
    """A scenario that cannot be used; the message names the field."""


@dataclass
class CarSpec:
    s: float             # [m]
    d: float             # [m]
    speed: float = 0.0   # [m/s] scripted cars keep their lane offset at this speed


@dataclass
class Scenario:
    track: Track
    ego: VehicleState
    cars: list[CarSpec] = field(default_factory=list)
    seed: int = 0


def _num(obj: dict, key: str, where: str, default=None, lo: float | None = None, hi: float | None = None,
         unit: str = "m") -> float:
    """obj[key] as a finite float within [lo, hi]; `default` when missing (None: required)."""
    if default is None:
        return number(obj, key, where, lo=lo, hi=hi, unit=unit, error=ScenarioError)
    return number(obj, key, where, lo=lo, hi=hi, unit=unit, default=float(default), error=ScenarioError)


def _check_on_road(track: Track, d: float, where: str) -> None:
    if not track.on_road(d, margin=EDGE_OUTSIDE):
        raise ScenarioError(f"{where}: d = {d:g} m is off the road (the road and its verges span "
                            f"±{track.half_width + EDGE_OUTSIDE:g} m)")


def _check_along(track: Track, s: float, where: str) -> float:
    if abs(s) > track.length:
        raise ScenarioError(f"{where}: 's' = {s:g} m is beyond the track: it must be from {-track.length:.1f} to "
                            f"{track.length:.1f} m (one lap of track '{track.name}')")
    return track.wrap_s(s)


def scenario_from_dict(obj, base_dir: Path | None = None, lanes: int | None = None) -> Scenario:
    """A scenario from its JSON object. Every field is checked before the track is built, except the
    positions, which are checked against the track."""
    if not isinstance(obj, dict):
        raise ScenarioError(f"a scenario must be a JSON object with {', '.join(SCENARIO_KEYS)}, got {show(obj)}")
    if "version" in obj:
        raise ScenarioError("this is a scripted scenario (it has a 'version'): it is driven, by benchmark --scenarios, "
                            "drive or studio --scenario, or Gymnasium's scenario=; probe and render read static "
                            "scenarios (docs/scenarios.md)")
    check_keys(obj, SCENARIO_KEYS, "scenario", ScenarioError)
    if "track" not in obj:
        raise ScenarioError("scenario: missing 'track' (a track object, a preset name, procedural:SEED or a "
                            "track file)")
    ref = obj["track"]
    if not isinstance(ref, (str, dict)):
        raise ScenarioError(f"scenario: 'track' must be a track object, a preset name, procedural:SEED or a "
                            f"track file, got {show(ref)}")
    if "lanes" in obj:
        n = obj["lanes"]
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_LANES:
            raise ScenarioError(f"scenario: lanes must be an integer from 1 to {MAX_LANES}, got {show(n)}")
    seed = number(obj, "seed", "scenario", lo=0, hi=MAX_SEED, default=0, integer=True, error=ScenarioError)

    ego = obj.get("ego")
    if not isinstance(ego, dict):
        raise ScenarioError(f"scenario: 'ego' must be an object with s, d, heading and speed, got {show(ego)}")
    check_keys(ego, EGO_KEYS, "ego", ScenarioError)
    ego_s, ego_d = _num(ego, "s", "ego"), _num(ego, "d", "ego")
    heading = _num(ego, "heading", "ego", 0.0, -MAX_HEADING, MAX_HEADING, "rad")
    speed = _num(ego, "speed", "ego", 0.0, 0.0, MAX_SPEED, "m/s")

    cars_in = obj.get("cars", [])
    if not isinstance(cars_in, list):
        raise ScenarioError(f"scenario: 'cars' must be a list of objects with s, d and speed, got {show(cars_in)}")
    if len(cars_in) > MAX_CARS:
        raise ScenarioError(f"scenario: 'cars' has {len(cars_in)} cars; a scenario may place at most {MAX_CARS}")
    cars_raw = []
    for i, c in enumerate(cars_in):
        where = f"car {i}"
        if not isinstance(c, dict):
            raise ScenarioError(f"{where}: expected an object with s, d and speed, got {show(c)}")
        check_keys(c, CAR_KEYS, where, ScenarioError)
        cars_raw.append((_num(c, "s", where), _num(c, "d", where), _num(c, "speed", where, 0.0, 0.0, MAX_SPEED, "m/s")))

    # every field is sound: now the track (the first real work)
    if isinstance(ref, str) and base_dir is not None and (ref.endswith(".json") or "/" in ref):
        ref = str((base_dir / ref) if not Path(ref).is_absolute() else Path(ref))
    track = load_track(ref, lanes=lanes if lanes is not None else obj.get("lanes"))
    state = VehicleState(s=_check_along(track, ego_s, "ego"), d=ego_d, heading=heading, speed=speed)
    _check_on_road(track, state.d, "ego")
    cars = []
    for i, (s, d, v) in enumerate(cars_raw):
        car = CarSpec(_check_along(track, s, f"car {i}"), d, v)
        _check_on_road(track, car.d, f"car {i}")
        cars.append(car)
    return Scenario(track, state, cars, seed)


def load_scenario(path, lanes: int | None = None) -> Scenario:
    """A scenario from a file; every refusal is one line that starts with the file's name."""
    path = Path(path)
    obj = read_json(path, "scenario", error=ScenarioError)
    try:
        return scenario_from_dict(obj, base_dir=path.parent, lanes=lanes)
    except (ScenarioError, TrackError) as e:
        raise type(e)(f"{show_path(path)}: {e}") from None
