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

from .track import Track, TrackError, load_track
from .track.trackfile import read_json
from .truth import EDGE_OUTSIDE
from .vehicle import VehicleState


class ScenarioError(ValueError):
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


def _num(obj: dict, key: str, where: str, default=None) -> float:
    if key not in obj:
        if default is None:
            raise ScenarioError(f"{where}: missing '{key}'")
        return float(default)
    v = obj[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ScenarioError(f"{where}: '{key}' must be a number, got {v!r}")
    return float(v)


def _check_on_road(track: Track, d: float, where: str) -> None:
    if not track.on_road(d, margin=EDGE_OUTSIDE):
        raise ScenarioError(f"{where}: d = {d:g} m is off the road (the road and its verges span "
                            f"±{track.half_width + EDGE_OUTSIDE:g} m)")


def scenario_from_dict(obj, base_dir: Path | None = None, lanes: int | None = None) -> Scenario:
    if not isinstance(obj, dict):
        raise ScenarioError("a scenario must be a JSON object")
    if "track" not in obj:
        raise ScenarioError("scenario: missing 'track'")
    ref = obj["track"]
    if isinstance(ref, str) and base_dir is not None and (ref.endswith(".json") or "/" in ref):
        ref = str((base_dir / ref) if not Path(ref).is_absolute() else Path(ref))
    lanes = lanes if lanes is not None else obj.get("lanes")
    track = load_track(ref, lanes=lanes)
    seed = obj.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"scenario: 'seed' must be a non-negative integer, got {seed!r}")
    ego = obj.get("ego")
    if not isinstance(ego, dict):
        raise ScenarioError("scenario: 'ego' must be an object with s, d, heading and speed")
    state = VehicleState(s=track.wrap_s(_num(ego, "s", "ego")), d=_num(ego, "d", "ego"),
                         heading=_num(ego, "heading", "ego", 0.0), speed=_num(ego, "speed", "ego", 0.0))
    _check_on_road(track, state.d, "ego")
    if state.speed < 0:
        raise ScenarioError(f"ego: 'speed' must not be negative, got {state.speed}")
    cars_in = obj.get("cars", [])
    if not isinstance(cars_in, list):
        raise ScenarioError("scenario: 'cars' must be a list")
    cars = []
    for i, c in enumerate(cars_in):
        where = f"car {i}"
        if not isinstance(c, dict):
            raise ScenarioError(f"{where}: expected an object with s and d")
        car = CarSpec(track.wrap_s(_num(c, "s", where)), _num(c, "d", where), _num(c, "speed", where, 0.0))
        _check_on_road(track, car.d, where)
        cars.append(car)
    return Scenario(track, state, cars, seed)


def load_scenario(path, lanes: int | None = None) -> Scenario:
    path = Path(path)
    try:
        obj = read_json(path)
    except TrackError as e:
        raise ScenarioError(str(e)) from None
    try:
        return scenario_from_dict(obj, base_dir=path.parent, lanes=lanes)
    except (ScenarioError, TrackError) as e:
        raise type(e)(f"{path}: {e}") from None
