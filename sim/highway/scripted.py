"""The scripted-scenario format (docs/scenarios.md, version 2): a route, cars placed relative to the host car, the
events that make them cut in, brake, stop, slow down or drive on their own, and what passes.

{"version": 2, "name": str, "description": str,
 "route": {"track": ..., "lanes": N, "traffic": AI cars, "seed": int, "seconds": s},
 "host": {"s": m, "lane": k (0 = leftmost), "speed": m/s, "offset": m, "heading": rad},
 "actors": [{"name": str, "lane_offset": +1 left / -1 right, "gap": m (centre to centre, + ahead), "speed": m/s,
             "model": "sedan" | ..., "blind": bool}, ...],
 "events": [{"actor": name, "when": {"time": s} | {"gap": m}, "do": "change_lane" | "brake" | "stop" | "slow" |
             "resume", ...}, ...],
 "pass": {"no_collision": bool, "kept_lane": bool, "min_time_gap": s}}

Every field is checked before anything is built but the track, and every refusal is one line that starts with the
file's name (ScenarioError: exit status 2). The static format (sim/highway/scenario.py) has no "version".
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from pathlib import Path

from core.inputs import check_keys, number, read_json, show, show_path
from sim.highway.footprints import FOOTPRINTS, MODEL_NAMES
from sim.highway.scenario import ScenarioError
from sim.track import Track, TrackError, load_track

VERSION = 2
MAX_SECONDS = 3600.0      # [s] a scenario is a moment, not a route: at most an hour
MAX_SEED = 2**32 - 1
MAX_TRAFFIC = 300         # SUMO's AI cars (sim/highway/config.py MAX_CARS)
MAX_HOST_SPEED = 60.0     # [m/s] the world's start_speed range
MAX_ACTOR_SPEED = 50.0    # [m/s] SUMO's vehicle types drive at most this fast (sim/highway/sumo_traffic.py)
MAX_OFFSET_SHARE = 0.5    # the host's offset from its lane centre is at most this share of the lane width
MAX_HEADING = 0.5         # [rad] the host's yaw relative to the road at the start
MAX_ACTORS = 64
MAX_EVENTS = 2000         # a clip's replay scripts every car's speed every half second
MAX_RATE = 15.0           # [m/s^2] a braking or speed-change rate: beyond any tyre's grip, so every real one fits
CLEARANCE = 0.5           # [m] bumper to bumper, the least two cars of one lane may be placed apart
STOP_DECEL = 4.0          # [m/s^2] "stop" without "decel": a firm, ordinary stop
SLOW_RATE = 1.5           # [m/s^2] "slow" without "rate": an unhurried change of speed
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]{0,63}")

KEYS = ("version", "name", "description", "route", "host", "actors", "events", "pass")
ROUTE_KEYS = ("track", "lanes", "traffic", "seed", "seconds")
HOST_KEYS = ("s", "lane", "speed", "offset", "heading")
ACTOR_KEYS = ("name", "lane_offset", "gap", "speed", "model", "blind")
PASS_KEYS = ("no_collision", "kept_lane", "min_time_gap")
TRIGGERS = ("time", "gap")
TOWARDS = ("host", "left", "right")
# what each event kind takes besides "actor", "when" and "do"
EVENT_FIELDS = {"change_lane": ("towards",), "brake": ("decel", "speed"), "stop": ("decel",),
                "slow": ("speed", "rate"), "resume": ("speed",)}


@dataclass(frozen=True)
class Host:
    s: float              # [m] along the centreline
    lane: int             # 0 = leftmost
    speed: float          # [m/s]
    offset: float = 0.0   # [m] from the lane's centre, positive left
    heading: float = 0.0  # [rad] yaw relative to the road, counter-clockwise positive


@dataclass(frozen=True)
class Actor:
    name: str
    lane_offset: int      # lanes left (+) or right (-) of the host's lane
    gap: float            # [m] centre to centre along the road, positive ahead of the host
    speed: float          # [m/s] it holds until an event changes it
    model: str = "sedan"
    blind: bool = False   # True: it follows its script even into the car ahead (a replayed clip's cars)

    @property
    def length(self) -> float:
        return FOOTPRINTS[self.model][0]


@dataclass(frozen=True)
class Event:
    actor: int            # index into the scenario's actors
    time: float | None    # [s] fires at the first step at or after this simulated time ...
    gap: float | None     # [m] ... or when the actor's gap to the host reaches this value
    do: str               # one of EVENT_FIELDS
    towards: str = "host"             # change_lane: "host", "left" or "right"
    speed: float | None = None        # [m/s] brake, slow: the speed it ends at; resume: the speed it wants
    rate: float | None = None         # [m/s^2] brake, stop: deceleration; slow: the rate of the change


@dataclass(frozen=True)
class Criteria:
    no_collision: bool = True
    kept_lane: bool = False
    min_time_gap: float | None = None   # [s] bumper to bumper over the host's speed, to the car ahead in its lane


@dataclass(frozen=True)
class ScriptedScenario:
    name: str
    description: str
    path: str                 # the file, absolute ("" when made in memory)
    track_ref: str            # what load_track reads (a track file's path made absolute)
    lanes: int
    traffic: int              # SUMO's AI cars besides the actors
    seed: int
    seconds: float
    host: Host
    actors: tuple[Actor, ...]
    events: tuple[Event, ...]
    criteria: Criteria
    track: Track = field(compare=False, repr=False, default=None)   # type: ignore[assignment]

    def configure(self, config):
        """The world's configuration (sim/highway/config.py) with this scenario's route: its track, lanes, traffic,
        seed and the host's start lane and speed."""
        return replace(config, track=self.track_ref, lanes=self.lanes, cars=self.traffic, seed=self.seed,
                       start_lane=self.host.lane, start_speed=self.host.speed, scenario=self.path or config.scenario)

    def placements(self) -> list[tuple[float, float, float, int]]:
        """(s [m], d [m], speed [m/s], model index) of every actor, at the start."""
        tr = self.track
        return [(float(tr.wrap_s(self.host.s + a.gap)), float(tr.lane_centres[self.host.lane - a.lane_offset]),
                 a.speed, MODEL_NAMES.index(a.model)) for a in self.actors]


# --- reading ------------------------------------------------------------------------------------------------------
def _obj(value, where: str, keys: tuple[str, ...]) -> dict:
    if not isinstance(value, dict):
        raise ScenarioError(f"{where} must be an object with {', '.join(keys)}, got {show(value)}")
    check_keys(value, keys, where, ScenarioError)
    return value


def _flag(obj: dict, key: str, where: str, default: bool) -> bool:
    v = obj.get(key, default)
    if not isinstance(v, bool):
        raise ScenarioError(f"{where}: '{key}' must be true or false, got {show(v)}")
    return v


def _text(obj: dict, key: str, where: str, default: str, pattern=None, limit: int = 2000) -> str:
    v = obj.get(key, default)
    if not isinstance(v, str) or not v or len(v) > limit or not v.isprintable() or \
            (pattern is not None and not pattern.fullmatch(v)):
        rule = "1 to 64 letters, digits, '_', '.', '+' or '-'" if pattern is not None else \
            f"one line of 1 to {limit} printable characters"
        raise ScenarioError(f"{where}: '{key}' must be {rule}, got {show(v)}")
    return v


def _route(obj, base: Path) -> tuple[str, Track, int, int, float]:
    r = _obj(obj, "route", ROUTE_KEYS)
    if not isinstance(r.get("track"), str):
        raise ScenarioError(f"route: 'track' must be a preset, procedural:SEED or a track file, got "
                            f"{show(r.get('track'))}")
    lanes = number(r, "lanes", "route", lo=1, hi=4, integer=True, default=None, error=ScenarioError)
    traffic = number(r, "traffic", "route", lo=0, hi=MAX_TRAFFIC, integer=True, default=0, error=ScenarioError)
    seed = number(r, "seed", "route", lo=0, hi=MAX_SEED, integer=True, default=0, error=ScenarioError)
    seconds = number(r, "seconds", "route", lo=0, lo_open=True, hi=MAX_SECONDS, unit="s", error=ScenarioError)
    ref = r["track"]
    if not ref.startswith("procedural:") and ("/" in ref or ref.endswith(".json")):
        ref = str(Path(ref) if Path(ref).is_absolute() else base / ref)
    try:
        track = load_track(ref, lanes=lanes)
    except TrackError as e:
        raise ScenarioError(f"route: track {show(r['track'], 60)}: {e}") from None
    from sim.highway.sumo_traffic import car_count_problem  # lazy: SUMO's module, once the fields are sound
    problem = car_count_problem(track, traffic)
    if problem:
        raise ScenarioError(f"route: 'traffic': {problem}")
    return ref, track, traffic, seed, seconds


def _host(obj, track: Track) -> Host:
    h = _obj(obj, "host", HOST_KEYS)
    s = number(h, "s", "host", lo=-track.length, hi=track.length, unit="m", default=0.0, error=ScenarioError)
    lane = number(h, "lane", "host", lo=0, hi=track.lanes - 1, integer=True, error=ScenarioError)
    speed = number(h, "speed", "host", lo=0, hi=MAX_HOST_SPEED, unit="m/s", error=ScenarioError)
    half = MAX_OFFSET_SHARE * track.lane_width
    offset = number(h, "offset", "host", lo=-half, hi=half, unit="m", default=0.0, error=ScenarioError)
    heading = number(h, "heading", "host", lo=-MAX_HEADING, hi=MAX_HEADING, unit="rad", default=0.0,
                     error=ScenarioError)
    return Host(float(track.wrap_s(s)), lane, speed, offset, heading)


def _actor(obj, i: int, host: Host, track: Track) -> Actor:
    where = f"actor {i}"
    a = _obj(obj, where, ACTOR_KEYS)
    name = _text(a, "name", where, f"actor{i}", NAME)
    where = f"actor {i} ('{name}')"
    offset = number(a, "lane_offset", where, lo=-3, hi=3, integer=True, default=0, error=ScenarioError)
    lane = host.lane - offset
    if not 0 <= lane < track.lanes:
        raise ScenarioError(f"{where}: 'lane_offset' {offset:+d} puts it off the road: the host is in lane "
                            f"{host.lane} of {track.lanes} (0 = leftmost), so lane offsets from "
                            f"{host.lane - track.lanes + 1:+d} to {host.lane:+d} are on it")
    half = track.length / 2 - 1.0
    gap = number(a, "gap", where, lo=-half, hi=half, unit="m", error=ScenarioError)
    speed = number(a, "speed", where, lo=0, hi=MAX_ACTOR_SPEED, unit="m/s", error=ScenarioError)
    model = a.get("model", "sedan")
    if model not in MODEL_NAMES:
        raise ScenarioError(f"{where}: 'model' must be one of {', '.join(MODEL_NAMES)}, got {show(model)}")
    return Actor(name, offset, gap, speed, model, _flag(a, "blind", where, False))


def _check_apart(actors: list[Actor]) -> None:
    """No two bodies (the host's included, a sedan's length, at gap 0 and lane offset 0) overlap in one lane."""
    bodies = [("the host", 0, 0.0, FOOTPRINTS["sedan"][0])] + [(f"actor '{a.name}'", a.lane_offset, a.gap, a.length)
                                                                for a in actors]
    for i, (na, la, ga, lena) in enumerate(bodies):
        for nb, lb, gb, lenb in bodies[i + 1:]:
            need = (lena + lenb) / 2 + CLEARANCE
            if la == lb and abs(ga - gb) < need:
                raise ScenarioError(f"{nb} is placed inside {na}: in one lane their centres {abs(ga - gb):g} m apart, "
                                    f"at least {need:g} m needed (half of each length and {CLEARANCE:g} m)")


def _event(obj, i: int, names: dict[str, int], seconds: float, track: Track) -> Event:
    where = f"event {i}"
    if not isinstance(obj, dict):
        raise ScenarioError(f"{where} must be an object with actor, when and do, got {show(obj)}")
    do = obj.get("do")
    if do not in EVENT_FIELDS:
        raise ScenarioError(f"{where}: 'do' must be one of {', '.join(EVENT_FIELDS)}, got {show(do)}")
    check_keys(obj, ("actor", "when", "do") + EVENT_FIELDS[do], f"{where} ({do})", ScenarioError)
    actor = obj.get("actor")
    if actor not in names:
        raise ScenarioError(f"{where}: 'actor' must name an actor ({', '.join(names) or 'there are none'}), "
                            f"got {show(actor)}")
    time, gap = _trigger(obj.get("when"), where, seconds, track)
    return Event(names[actor], time, gap, do, **_action(obj, do, where))


def _trigger(when, where: str, seconds: float, track: Track) -> tuple[float | None, float | None]:
    """(time, gap) of an event's `when`, one of them None; a trigger that can never fire is refused."""
    when = _obj(when, f"{where}: 'when'", TRIGGERS)
    if len(when) != 1:
        raise ScenarioError(f"{where}: 'when' must hold one of 'time' [s] and 'gap' [m], got {show(when)}")
    time = gap = None
    if "time" in when:
        time = number(when, "time", f"{where}: when", lo=0, unit="s", error=ScenarioError)
        if time >= seconds:
            raise ScenarioError(f"{where}: its trigger can never fire: 'time' {time:g} s is not before the "
                                f"scenario's end ({seconds:g} s)")
    else:
        half = track.length / 2 - 1.0
        gap = number(when, "gap", f"{where}: when", unit="m", error=ScenarioError)
        if abs(gap) > half:
            raise ScenarioError(f"{where}: its trigger can never fire: gaps along this track are measured within "
                                f"half a lap, -{half:g} to {half:g} m, got {gap:g}")
    return time, gap


def _action(obj: dict, do: str, where: str) -> dict:
    """The fields of an event's kind: towards, speed and rate (a brake's or stop's "decel")."""
    kw: dict = {}
    if do == "change_lane":
        kw["towards"] = obj.get("towards", "host")
        if kw["towards"] not in TOWARDS:
            raise ScenarioError(f"{where}: 'towards' must be one of {', '.join(TOWARDS)}, got {show(kw['towards'])}")
    if do in ("brake", "stop"):
        if do == "stop":
            kw["rate"] = number(obj, "decel", where, lo=0, lo_open=True, hi=MAX_RATE, unit="m/s^2",
                                default=STOP_DECEL, error=ScenarioError)
        else:   # a brake says how hard
            kw["rate"] = number(obj, "decel", where, lo=0, lo_open=True, hi=MAX_RATE, unit="m/s^2",
                                error=ScenarioError)
        kw["speed"] = 0.0 if do == "stop" else number(obj, "speed", where, lo=0, hi=MAX_ACTOR_SPEED, unit="m/s",
                                                      default=0.0, error=ScenarioError)
    if do == "slow":
        kw["speed"] = number(obj, "speed", where, lo=0, hi=MAX_ACTOR_SPEED, unit="m/s", error=ScenarioError)
        kw["rate"] = number(obj, "rate", where, lo=0, lo_open=True, hi=MAX_RATE, unit="m/s^2", default=SLOW_RATE,
                            error=ScenarioError)
    if do == "resume" and "speed" in obj:
        kw["speed"] = number(obj, "speed", where, lo=0, lo_open=True, hi=MAX_ACTOR_SPEED, unit="m/s",
                             error=ScenarioError)
    return kw


def _criteria(obj) -> Criteria:
    p = _obj(obj, "pass", PASS_KEYS)
    gap = number(p, "min_time_gap", "pass", lo=0, lo_open=True, hi=10, unit="s", default=None, error=ScenarioError)
    return Criteria(_flag(p, "no_collision", "pass", True), _flag(p, "kept_lane", "pass", False), gap)


def _list(obj: dict, key: str, limit: int) -> list:
    items = obj.get(key, [])
    if not isinstance(items, list) or len(items) > limit:
        raise ScenarioError(f"'{key}' must be a list of at most {limit}, got "
                            f"{show(items) if not isinstance(items, list) else f'{len(items)}'}")
    return items


def scripted_from_dict(obj, base: Path, default_name: str = "scenario", path: str = "") -> ScriptedScenario:
    """A scripted scenario from its JSON object; `base` is the folder track files are found in."""
    if not isinstance(obj, dict):
        raise ScenarioError(f"a scenario must be a JSON object, got {show(obj)}")
    if "version" not in obj:
        raise ScenarioError("this is a static scenario (no 'version'): probe and render read it; a scenario that is "
                            "driven has \"version\": 2 (docs/scenarios.md)")
    if obj["version"] != VERSION or isinstance(obj["version"], bool):
        raise ScenarioError(f"'version' must be {VERSION}, got {show(obj['version'])}")
    check_keys(obj, KEYS, "scenario", ScenarioError)
    name = _text(obj, "name", "scenario", default_name, NAME)
    description = _text(obj, "description", "scenario", "-")
    for key in ("route", "host"):
        if key not in obj:
            raise ScenarioError(f"missing '{key}'")
    actors_in, events_in = _list(obj, "actors", MAX_ACTORS), _list(obj, "events", MAX_EVENTS)
    criteria = _criteria(obj.get("pass", {}))
    ref, track, traffic, seed, seconds = _route(obj["route"], base)
    host = _host(obj["host"], track)
    actors = [_actor(a, i, host, track) for i, a in enumerate(actors_in)]
    names: dict[str, int] = {}
    for i, a in enumerate(actors):
        if a.name in names:
            raise ScenarioError(f"two actors are named '{a.name}'; actor names must be unique")
        names[a.name] = i
    _check_apart(actors)
    events = tuple(_event(e, i, names, seconds, track) for i, e in enumerate(events_in))
    return ScriptedScenario(name, description, path, ref, track.lanes, traffic, seed, seconds, host, tuple(actors),
                            events, criteria, track)


def load_scripted(path) -> ScriptedScenario:
    """The scripted scenario in the file `path`, checked whole; every refusal is one line naming the file."""
    p = Path(path)
    obj = read_json(p, "scenario", error=ScenarioError)
    stem = p.stem if NAME.fullmatch(p.stem) else "scenario"
    try:
        return scripted_from_dict(obj, p.resolve().parent, stem, str(p.resolve()))
    except ScenarioError as e:
        raise ScenarioError(f"{show_path(p)}: {e}") from None
