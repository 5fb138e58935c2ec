"""Every JSON input file refuses a value of the wrong type in one line, whatever the value and wherever it stands.

For each reader (track, scenario, benchmark suite, sidewalk path, obstacle file) a valid file is taken and every
value in it, one at a time, is replaced by a list, an object, a string, a boolean, null and a huge number. The
reader must accept the file or refuse it with its input error (one line, exit status 2 in the CLI); any other
exception (a TypeError from hashing a list, an AttributeError from calling a string method on a number) is the
traceback a user would see.
"""
from __future__ import annotations

import json
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from drivestudio.errors import input_errors
from drivestudio.worlds.highway.benchmark import load_suite
from sim.highway.scenario import load_scenario
from sim.sidewalk.layout import obstacles_from_file
from sim.sidewalk.paths import load_path
from sim.track import load_track

REPO = Path(__file__).resolve().parents[2]
WRONG = ([1.0], {"x": 1.0}, "x", True, None, 1e308)
OBSTACLES = {"obstacles": [{"kind": "cone", "s": 12.0, "d": 0.4}, {"kind": "bench", "s": 40.0, "d": -0.6,
                                                                    "yaw_deg": 0}]}


def _paths(obj, at=()) -> Iterator[tuple]:
    """The path (keys and indices) of every value inside `obj`, containers included."""
    items = obj.items() if isinstance(obj, dict) else enumerate(obj) if isinstance(obj, list) else ()
    for key, value in items:
        yield at + (key,)
        yield from _paths(value, at + (key,))


def _replaced(obj, path: tuple, value):
    obj = json.loads(json.dumps(obj))
    parent = obj
    for key in path[:-1]:
        parent = parent[key]
    parent[path[-1]] = value
    return obj


def _readers(tmp: Path) -> dict[str, tuple[dict, Callable[[Path], object]]]:
    park = load_path("park")
    shutil.copy(REPO / "assets" / "tracks" / "oval.json", tmp / "oval.json")   # what the scenario names
    suite = json.loads((REPO / "assets" / "suites" / "default.json").read_text())
    suite["routes"] = suite["routes"][:2]
    return {
        "track": (json.loads((REPO / "assets" / "tracks" / "oval.json").read_text()), load_track),
        "scenario": (json.loads((REPO / "docs" / "examples" / "three-lane.json").read_text()), load_scenario),
        "suite": (suite, load_suite),
        "path": (json.loads((REPO / "assets" / "paths" / "park.json").read_text()), load_path),
        "obstacles": (OBSTACLES, lambda f: obstacles_from_file(park, f)),
    }


@pytest.mark.parametrize("reader", ["track", "scenario", "suite", "path", "obstacles"])
def test_a_value_of_the_wrong_type_is_refused_in_one_line(tmp_path, reader):
    valid, read = _readers(tmp_path)[reader]
    refused = input_errors()
    tried = 0
    for path in _paths(valid):
        for value in WRONG:
            f = tmp_path / f"{reader}.json"
            f.write_text(json.dumps(_replaced(valid, path, value)))
            try:
                read(f)
            except refused as e:
                assert "\n" not in str(e)
            except Exception as e:   # anything else reaches the user as a traceback
                pytest.fail(f"{reader}: {'/'.join(map(str, path))} = {value!r} raised {type(e).__name__}: {e}")
            tried += 1
    assert tried >= 6 * 5
