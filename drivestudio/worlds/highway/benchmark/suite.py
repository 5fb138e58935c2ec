"""The suite file format (docs/benchmark.md): the fixed routes a benchmark drives every model on.

{"name": str (optional, default: the file's name), "description": str (optional),
 "generator": {"seed", "routes", "lanes", "cars", "seconds"} (optional: how draw.py drew the routes),
 "routes": [{"name": str, "track": preset | "procedural:SEED" | track file (relative to the suite file),
             "lanes": 1..4 (optional, default the track's), "cars": AI cars 0..300, "seed": traffic seed,
             "start_lane": 0..lanes-1 counted from the left (optional, default drawn from the seed),
             "seconds": simulated seconds of the route}, ...]}

A suite is checked whole before anything is driven: malformed JSON, unknown fields, an unknown track, a lane
count or start lane out of range, NaN, negative or absurd numbers, more cars than the track holds: one line
naming the file, the route and the field (SuiteError, a UsageError: exit status 2).
"""
from __future__ import annotations

import hashlib
import re
from dataclasses import asdict, dataclass
from pathlib import Path

from assets import ASSETS_DIR
from core.inputs import check_keys, number, read_bytes, read_json, show, show_path
from drivestudio.errors import UsageError
from sim.track import MAX_LANES, TrackError, load_track

SUITES_DIR = ASSETS_DIR / "suites"
DEFAULT_SUITE = SUITES_DIR / "default.json"

SUITE_KEYS = ("name", "description", "generator", "routes")
GENERATOR_KEYS = ("seed", "routes", "lanes", "cars", "seconds")
ROUTE_KEYS = ("name", "track", "lanes", "cars", "seed", "start_lane", "seconds")
MAX_ROUTES = 200
MAX_SECONDS = 7200.0          # [s] two simulated hours per route
MIN_SECONDS = 1.0             # [s]
MAX_CARS = 300                # SUMO's AI cars (sim/highway/sumo_traffic.py)
MAX_SEED = 2**32 - 1
MAX_TEXT = 2000               # characters of a description
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]{0,63}")   # route and suite names: used in file names


class SuiteError(UsageError):
    """A suite that cannot be driven; the message is one line naming the file, the route and the field."""


@dataclass(frozen=True)
class Route:
    name: str
    track: str               # as given: a preset, procedural:SEED, or a track file (resolved, see `track_ref`)
    lanes: int               # resolved: the track's own count when the suite gives none
    cars: int
    seed: int
    start_lane: int | None   # 0 = leftmost; None: drawn from the seed (sim/highway/world.py)
    seconds: float
    track_ref: str = ""      # what load_track reads (a track file's path made absolute)
    length_m: float = 0.0    # [m] one lap of the track
    scenario: str = ""       # a scripted scenario's file (scenarios.py): it sets the route's start and drives its cars

    def as_dict(self) -> dict:
        d = asdict(self)
        d.pop("track_ref")
        if not d["scenario"]:   # a suite's route: the fields of the suite file
            d.pop("scenario")
        return d


@dataclass(frozen=True)
class Suite:
    name: str
    description: str
    routes: tuple[Route, ...]
    path: str
    sha256: str
    generator: dict | None = None   # a drawn suite's generator (draw.py): seed, routes, lanes, cars, seconds

    @property
    def seconds(self) -> float:
        return sum(r.seconds for r in self.routes)

    def select(self, names: list[str]) -> Suite:
        """The suite cut down to the named routes, in the suite's order."""
        known = {r.name for r in self.routes}
        unknown = [n for n in names if n not in known]
        if unknown:
            raise SuiteError(f"--routes: no route {show(unknown[0])} in suite '{self.name}' (routes: "
                             f"{', '.join(r.name for r in self.routes)})")
        return Suite(self.name, self.description, tuple(r for r in self.routes if r.name in names), self.path,
                     self.sha256, self.generator)

    def as_dict(self) -> dict:
        return {"name": self.name, "description": self.description, "path": self.path, "sha256": self.sha256,
                **({"generator": self.generator} if self.generator else {}),
                "routes": [r.as_dict() for r in self.routes]}


def _text(obj: dict, key: str, where: str, default: str | None = None, pattern=None, limit: int = MAX_TEXT) -> str:
    if key not in obj:
        if default is None:
            raise SuiteError(f"{where}: missing '{key}'")
        return default
    v = obj[key]
    if not isinstance(v, str) or not v or len(v) > limit or not v.isprintable():
        raise SuiteError(f"{where}: '{key}' must be a line of 1 to {limit} printable characters, got {show(v)}")
    if pattern is not None and not pattern.fullmatch(v):
        raise SuiteError(f"{where}: '{key}' must be 1 to 64 letters, digits, '_', '.', '+' or '-' (starting with "
                         f"a letter or digit), got {show(v)}")
    return v


def _track_ref(track: str, base: Path) -> str:
    """A track file named relative to the suite file is found beside it; presets and procedural:SEED as given."""
    if track.startswith("procedural:") or ("/" not in track and not track.endswith(".json")):
        return track
    p = Path(track)
    return str(p if p.is_absolute() else base / p)


def _route(obj, i: int, base: Path) -> Route:
    where = f"route {i}"
    if not isinstance(obj, dict):
        raise SuiteError(f"{where}: expected an object with {', '.join(ROUTE_KEYS)}, got {show(obj)}")
    check_keys(obj, ROUTE_KEYS, where, SuiteError, kind="a route")
    name = _text(obj, "name", where, pattern=NAME, limit=64)
    where = f"route {i} ('{name}')"
    track = _text(obj, "track", where, limit=300)
    lanes = number(obj, "lanes", where, lo=1, hi=MAX_LANES, integer=True, default=None, error=SuiteError)
    cars = number(obj, "cars", where, lo=0, hi=MAX_CARS, integer=True, error=SuiteError)
    seed = number(obj, "seed", where, lo=0, hi=MAX_SEED, integer=True, error=SuiteError)
    seconds = number(obj, "seconds", where, lo=MIN_SECONDS, hi=MAX_SECONDS, unit="s", error=SuiteError)
    ref = _track_ref(track, base)
    try:
        tr = load_track(ref, lanes=lanes)
    except TrackError as e:
        raise SuiteError(f"{where}: track {show(track, 60)}: {e}") from None
    start = number(obj, "start_lane", where, lo=0, hi=tr.lanes - 1, integer=True, default=None, error=SuiteError)
    from sim.highway.sumo_traffic import MIN_SPACING  # lazy: the SUMO traffic module (trimesh, PIL)
    capacity = int(tr.lanes * tr.length / MIN_SPACING)
    if cars > capacity:
        raise SuiteError(f"{where}: {cars} cars do not fit on track {show(track, 60)} with {tr.lanes} lane(s) "
                         f"({tr.length:.0f} m): at most {capacity}")
    return Route(name, track, tr.lanes, cars, seed, start, seconds, ref, round(float(tr.length), 1))


def _range(obj: dict, key: str, where: str, lo: int, hi: int) -> list[int]:
    v = obj.get(key)
    if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, int) and not isinstance(x, bool) for x in v)
            and lo <= v[0] <= v[1] <= hi):
        raise SuiteError(f"{where}: '{key}' must be [LO, HI], integers with {lo} <= LO <= HI <= {hi}, got {show(v)}")
    return list(v)


def _generator(obj, where: str = "generator") -> dict:
    """The optional record of how a suite was drawn (draw.py): checked, so that it can be drawn again."""
    if not isinstance(obj, dict):
        raise SuiteError(f"'generator' must be an object with {', '.join(GENERATOR_KEYS)}, got {show(obj)}")
    check_keys(obj, GENERATOR_KEYS, where, SuiteError)
    missing = [k for k in GENERATOR_KEYS if k not in obj]
    if missing:
        raise SuiteError(f"{where}: missing '{missing[0]}'")
    return {"seed": number(obj, "seed", where, lo=0, hi=MAX_SEED, integer=True, error=SuiteError),
            "routes": number(obj, "routes", where, lo=1, hi=MAX_ROUTES, integer=True, error=SuiteError),
            "lanes": _range(obj, "lanes", where, 1, MAX_LANES), "cars": _range(obj, "cars", where, 0, MAX_CARS),
            "seconds": number(obj, "seconds", where, lo=MIN_SECONDS, hi=MAX_SECONDS, unit="s", error=SuiteError)}


def parse_suite(obj, source: str, base: Path, sha256: str = "", default_name: str = "suite") -> Suite:
    """A Suite from the parsed JSON of a suite file (`source` names it in messages; `base` is its folder)."""
    try:
        if not isinstance(obj, dict):
            raise SuiteError(f"a suite must be a JSON object with {', '.join(SUITE_KEYS)}, got {show(obj)}")
        check_keys(obj, SUITE_KEYS, "suite", SuiteError)
        name = _text(obj, "name", "suite", default=default_name, pattern=NAME, limit=64)
        description = _text(obj, "description", "suite", default="-")
        gen = _generator(obj["generator"]) if "generator" in obj else None
        routes = obj.get("routes")
        if not isinstance(routes, list) or not routes or len(routes) > MAX_ROUTES:
            raise SuiteError(f"'routes' must be a list of 1 to {MAX_ROUTES} routes, got "
                             f"{show(routes) if not isinstance(routes, list) else f'{len(routes)} routes'}")
        parsed = tuple(_route(r, i, base) for i, r in enumerate(routes))
        seen: set[str] = set()
        for r in parsed:
            if r.name in seen:
                raise SuiteError(f"two routes are named '{r.name}'; route names must be unique")
            seen.add(r.name)
    except SuiteError as e:
        raise SuiteError(f"{source}: {e}") from None
    return Suite(name, description, parsed, source, sha256, gen)


def shipped_or_file(ref: str, folder: Path, flag: str, kind: str, error: type[Exception]) -> Path:
    """The file `ref` names: a shipped file's name (folder/NAME.json) or a path; a path that exists wins over a
    name, and an unknown name is refused with the shipped names."""
    path = folder / f"{ref}.json" if NAME.fullmatch(ref) and not Path(ref).exists() else Path(ref)
    if not path.exists() and path.parent == folder:
        names = ", ".join(sorted(p.stem for p in folder.glob("*.json")))
        raise error(f"{flag} {show(ref)}: no such {kind} (shipped: {names}; or a {kind} file)")
    return path


def suite_path(ref=None) -> Path:
    """The file of a suite given as a shipped suite's name (assets/suites/NAME.json: default, random, the design
    suites) or as a path. None: the shipped held-out suite."""
    return DEFAULT_SUITE if ref is None else shipped_or_file(str(ref), SUITES_DIR, "--suite", "suite", SuiteError)


def load_suite(ref=None) -> Suite:
    """The suite named `ref` (a shipped suite's name or a suite file; default: the shipped held-out suite), checked
    whole."""
    path = suite_path(ref)
    obj = read_json(path, "suite", error=SuiteError)   # the bounded, strict reader of every JSON input
    sha256 = hashlib.sha256(read_bytes(path, "suite", error=SuiteError)).hexdigest()
    source = show_path(path)
    stem = path.stem if NAME.fullmatch(path.stem) else "suite"
    return parse_suite(obj, source, path.resolve().parent, sha256, stem)
