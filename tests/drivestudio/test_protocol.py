"""The generalisation protocol (docs/generalisation.md): the shipped split is the one its seed draws, every cell
drives its split's routes in each of its conditions with its traffic, bad protocol files get one line and exit
status 2 before any work, and a run writes one table with the oracles' rows first."""
from __future__ import annotations

import csv
import json

import pytest

from drivestudio.worlds.highway.benchmark.protocol import (
    DENSITY,
    PROTOCOLS_DIR,
    SPLITS,
    TRAFFIC,
    ProtocolError,
    draw_protocol,
    load_protocol,
    parse_protocol,
    protocol_text,
)


def tiny(**change) -> dict:
    """One route a split of 3 simulated seconds on short tracks."""
    d = {"name": "tiny", "conditions": {"training": ["clear"], "new": ["fog", "night"]},
         "tracks": {"training": ["oval"], "new": ["procedural:5"]},
         "traffic": {"empty": 0, "regular": 2, "dense": 6}, "seconds": 3,
         "routes": {"training": [{"name": "a", "track": "oval", "lanes": 2, "seed": 1, "start_lane": 0}],
                    "new": [{"name": "b", "track": "procedural:5", "lanes": 1, "seed": 2, "start_lane": 0}]}}
    d.update(change)
    return d


def test_the_shipped_protocol_is_what_its_seed_draws():
    text = (PROTOCOLS_DIR / "generalisation.json").read_text()
    assert text == protocol_text(json.loads(text)["generator"]["seed"])


def test_the_split_keeps_training_and_new_apart_and_covers_every_condition():
    d = draw_protocol(7)
    for key in ("conditions", "tracks"):
        assert not set(d[key]["training"]) & set(d[key]["new"])
    assert sorted(d["conditions"]["training"] + d["conditions"]["new"]) == \
        sorted(["clear", "overcast", "low_sun", "night", "fog", "rain"])
    for s in SPLITS:
        assert all(r["track"] in d["tracks"][s] for r in d["routes"][s])
    assert d["tracks"]["training"][-1].startswith("procedural:") and int(d["tracks"]["training"][-1][11:]) % 1000 < 3
    assert int(d["tracks"]["new"][-1][11:]) % 1000 >= 3    # a procedural track no training plan drives


def test_every_cell_drives_its_splits_routes_in_its_conditions_with_its_traffic():
    p = parse_protocol(tiny(), "tiny.json")
    assert len(p.cells) == 12 and len({c.name for c in p.cells}) == 12
    for cell in p.cells:
        conditions = tiny()["conditions"][cell.conditions]
        assert cell.condition == ",".join(conditions)
        # the split's one route, once in each of the split's conditions
        assert [r.name for r in cell.suite.routes] == [f"{cell.name}.{tiny()['routes'][cell.tracks][0]['name']}.{c}"
                                                       for c in conditions]
        assert {r.track for r in cell.suite.routes} == {tiny()["routes"][cell.tracks][0]["track"]}
        assert [(c, [r.name for r in s.routes]) for c, s in cell.by_condition()] == \
            [(c, [f"{cell.name}.{tiny()['routes'][cell.tracks][0]['name']}.{c}"]) for c in conditions]
    cars = {(c.tracks, c.traffic): c.suite.routes[0] for c in p.cells}
    assert [cars[("training", t)].cars for t in TRAFFIC] == \
        [round(d * 2 * cars[("training", "empty")].length_m / 1000) for d in (0, 2, 6)]
    assert DENSITY["empty"] == 0 < DENSITY["regular"] < DENSITY["dense"]


@pytest.mark.parametrize("change, message", [
    ({"conditions": {"training": ["clear"], "new": ["drizzle"]}}, "unknown condition 'drizzle'"),
    ({"conditions": {"training": ["clear"], "new": []}}, "'new' must be a list of 1 to 50 names"),
    ({"conditions": {"training": ["clear", "fog"], "new": ["fog"]}}, "fog is both a training and a new one"),
    ({"tracks": {"training": ["oval"], "new": ["oval"]}}, "oval is both a training and a new one"),
    ({"weather": 1}, "unknown field 'weather'"),
    ({"traffic": {"empty": 0, "regular": 2, "dense": 90}}, "dense"),
    ({"routes": {"training": [{"name": "a", "track": "ring", "lanes": 2, "seed": 1, "start_lane": 0}],
                 "new": [{"name": "b", "track": "procedural:5", "lanes": 1, "seed": 2}]}},
     "track 'ring' is not one of the training tracks"),
])
def test_a_bad_protocol_gets_one_line_and_status_2_before_any_work(run_cli, tmp_path, change, message):
    path = tmp_path / "p.json"
    path.write_text(json.dumps(tiny(**change)))
    with pytest.raises(ProtocolError):
        load_protocol(str(path))
    r = run_cli("benchmark", "--protocol", path, "--out", tmp_path / "out")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and message in r.stderr, r.stderr
    assert not (tmp_path / "out").exists()


def test_an_unknown_protocol_name_and_a_suite_beside_it_are_refused(run_cli, tmp_path):
    r = run_cli("benchmark", "--protocol", "nocrash", "--out", tmp_path / "out")
    assert r.returncode == 2 and "no such protocol (shipped: generalisation" in r.stderr
    r = run_cli("benchmark", "--protocol", "generalisation", "--suite", "x.json")
    assert r.returncode == 2 and "give one" in r.stderr


@pytest.mark.long
def test_a_run_writes_one_table_with_the_oracles_rows_first(run_cli, tmp_path):
    path = tmp_path / "p.json"
    path.write_text(json.dumps(tiny()))
    r = run_cli("benchmark", "--protocol", path, "--workers", "2", "--clips", "0", "--out", tmp_path / "out")
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader((tmp_path / "out" / "protocol.csv").open()))
    assert [row["model"] for row in rows[:12]] == ["oracle"] * 12 and rows[12]["model"] == "oracle-extended"
    assert len(rows) == 24 and {row["cell"] for row in rows} == {c.name for c in parse_protocol(tiny(), "t").cells}
    assert all(float(row["success_rate"]) == 1.0 and float(row["driving_score"]) == 1.0 for row in rows)
    report = json.loads((tmp_path / "out" / "protocol.json").read_text())
    new = [c for c in report["cells"] if c["cell"].startswith("new-cond")][0]["board"]["models"][0]["routes"]
    assert sorted(r["condition"] for r in new) == ["fog", "night"]   # the route in each new condition
    assert "| oracle | train-cond.train-tracks.empty | 1 | 100.0% | 100% |" in \
        (tmp_path / "out" / "protocol.md").read_text()
