"""Bad scripted scenarios are refused in one line naming the file and the field, exit status 2, before any work:
an unknown event, an actor off the road or inside another, a trigger that can never fire, a file too large."""
import json

import pytest

from core.inputs import MAX_JSON_BYTES
from sim.highway.scenario import ScenarioError, load_scenario
from sim.highway.scripted import MAX_ACTORS, load_scripted


def good(**over):
    obj = {"version": 2, "route": {"track": "oval", "lanes": 3, "seconds": 10},
           "host": {"s": 0, "lane": 1, "speed": 20},
           "actors": [{"name": "lead", "gap": 30, "speed": 15}, {"name": "side", "lane_offset": 1, "gap": 10,
                                                                 "speed": 18}],
           "events": [{"actor": "lead", "when": {"time": 2}, "do": "brake", "decel": 6},
                      {"actor": "side", "when": {"gap": 15}, "do": "change_lane"}]}
    obj.update(over)
    return obj


def write(tmp_path, obj, name="s.json"):
    path = tmp_path / name
    path.write_text(obj if isinstance(obj, str) else json.dumps(obj))
    return path


def refused(tmp_path, obj, *needles):
    path = write(tmp_path, obj)
    with pytest.raises(ScenarioError) as info:
        load_scripted(path)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(str(path)), msg
    for needle in needles:
        assert needle in msg, (needle, msg)
    return msg


def actors(*extra):
    return good()["actors"] + list(extra)


def event(**fields):
    return good(events=[{"actor": "lead", "when": {"time": 1}, **fields}])


def test_a_good_scenario_reads(tmp_path):
    sc = load_scripted(write(tmp_path, good()))
    assert [a.name for a in sc.actors] == ["lead", "side"] and sc.events[0].rate == 6 and sc.events[0].speed == 0


@pytest.mark.parametrize("obj, needles", [
    (event(do="teleport"), ("event 0", "'do' must be one of change_lane, brake, stop, slow, resume", "'teleport'")),
    (event(do="brake"), ("event 0", "missing 'decel'")),
    (event(do="brake", decel=-3), ("event 0", "'decel' must be")),
    (event(do="stop", speed=3), ("event 0 (stop)", "unknown field 'speed'", "the fields are actor, when, do, decel")),
    (event(do="change_lane", towards="up"), ("'towards' must be one of host, left, right",)),
    (good(events=[{"actor": "ghost", "when": {"time": 1}, "do": "stop"}]), ("'actor' must name an actor",
                                                                           "lead, side", "'ghost'")),
    (event(do="stop", when={"time": 1, "gap": 3}), ("'when' must hold one of 'time' [s] and 'gap' [m]",)),
    (event(do="stop", when={"speed": 3}), ("unknown field 'speed'",)),
])
def test_an_unknown_or_malformed_event_is_refused(tmp_path, obj, needles):
    refused(tmp_path, obj, *needles)


@pytest.mark.parametrize("when, needles", [
    ({"time": 10}, ("its trigger can never fire", "'time' 10 s is not before the scenario's end (10 s)")),
    ({"time": 1e6}, ("its trigger can never fire",)),
    ({"gap": 5000}, ("its trigger can never fire", "within half a lap")),
])
def test_a_trigger_that_can_never_fire_is_refused(tmp_path, when, needles):
    refused(tmp_path, good(events=[{"actor": "lead", "when": when, "do": "stop"}]), "event 0", *needles)


@pytest.mark.parametrize("actor, needles", [
    ({"name": "x", "lane_offset": 2, "gap": 50, "speed": 10}, ("actor 2 ('x')", "puts it off the road",
                                                               "lane offsets from -1 to +1")),
    ({"name": "x", "lane_offset": -5, "gap": 50, "speed": 10}, ("'lane_offset' must be an integer from -3 to 3",)),
    ({"name": "x", "gap": 1e5, "speed": 10}, ("actor 2 ('x')", "'gap' must be")),
    ({"name": "x", "gap": 50, "speed": 80}, ("'speed' must be a number from 0 to 50 m/s",)),
    ({"name": "x", "gap": 50, "speed": 10, "model": "bus"}, ("'model' must be one of sedan",)),
    ({"name": "x", "gap": 50, "sped": 10}, ("unknown field 'sped' (did you mean 'speed'?)",)),
    ({"name": "x", "gap": 50, "speed": 10, "blind": 1}, ("'blind' must be true or false",)),
])
def test_an_actor_off_the_road_or_out_of_range_is_refused(tmp_path, actor, needles):
    refused(tmp_path, good(actors=actors(actor)), *needles)


def test_an_actor_inside_another_or_inside_the_host_is_refused(tmp_path):
    refused(tmp_path, good(actors=actors({"name": "x", "gap": 33, "speed": 10})),
            "actor 'x' is placed inside actor 'lead'", "3 m apart", "at least 5.1 m")
    refused(tmp_path, good(actors=actors({"name": "x", "gap": -2, "speed": 10})),
            "actor 'x' is placed inside the host")
    refused(tmp_path, good(actors=actors({"name": "lead", "gap": 80, "speed": 10})), "two actors are named 'lead'")


@pytest.mark.parametrize("over, needles", [
    ({"version": 3}, ("'version' must be 2, got 3",)),
    ({"colour": "red"}, ("unknown field 'colour'",)),
    ({"route": {"track": "oval", "seconds": 0}}, ("route: 'seconds' must be positive and at most 3600 s",)),
    ({"route": {"track": "nowhere", "seconds": 5}}, ("unknown track preset 'nowhere'",)),
    ({"route": {"track": "oval", "seconds": 5, "traffic": 900}}, ("route: 'traffic' must be",)),
    ({"route": {"track": "oval", "lanes": 3, "seconds": 5}, "host": {"lane": 3, "speed": 20}},
     ("host: 'lane' must be an integer from 0 to 2",)),
    ({"pass": {"no_collision": "yes"}}, ("pass: 'no_collision' must be true or false",)),
    ({"pass": {"min_time_gap": -1}}, ("pass: 'min_time_gap' must be",)),
    ({"actors": [{"gap": 10, "speed": 5}] * (MAX_ACTORS + 1)}, (f"'actors' must be a list of at most {MAX_ACTORS}",)),
])
def test_a_bad_route_host_or_criterion_is_refused(tmp_path, over, needles):
    refused(tmp_path, good(**over), *needles)


def test_nan_and_a_file_too_large_are_refused_before_parsing(tmp_path):
    refused(tmp_path, json.dumps(good()).replace('"speed": 15', '"speed": NaN'), "NaN is not allowed")
    big = json.dumps(good(description="x" * 100)) + " " * MAX_JSON_BYTES
    refused(tmp_path, big, f"may be at most {MAX_JSON_BYTES} bytes")


def test_each_format_names_the_other_when_given_it(tmp_path):
    static = write(tmp_path, {"track": "oval", "ego": {"s": 0, "d": 0}}, "static.json")
    with pytest.raises(ScenarioError, match="static scenario .no 'version'.: probe and render read it"):
        load_scripted(static)
    with pytest.raises(ScenarioError, match="scripted scenario .it has a 'version'.: it is driven"):
        load_scenario(write(tmp_path, good(), "scripted.json"))


@pytest.mark.parametrize("argv", [
    ("benchmark", "--scenarios", "{bad}", "--out", "{out}"),
    ("drive", "--scenario", "{bad}", "--seconds", "1", "--out", "{out}"),
    ("probe", "{bad}"),
])
def test_the_verbs_refuse_a_bad_scenario_in_one_line_with_exit_status_2(tmp_path, run_cli, argv):
    bad = write(tmp_path, good(events=[{"actor": "lead", "when": {"time": 1}, "do": "teleport"}]), "bad.json")
    out = tmp_path / "out"
    run = run_cli(*(a.format(bad=bad, out=out) for a in argv))
    assert run.returncode == 2, run
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and ("'do' must be one of" in lines[0] or "scripted scenario" in lines[0]), lines
    assert not (out / "leaderboard.json").exists()


def test_benchmark_refuses_a_suite_and_scenarios_together_and_an_empty_folder(tmp_path, run_cli):
    run = run_cli("benchmark", "--suite", "x.json", "--scenarios", str(tmp_path))
    assert run.returncode == 2 and "--suite, --scenarios and --protocol" in run.stderr
    run = run_cli("benchmark", "--scenarios", str(tmp_path))
    assert run.returncode == 2 and "holds no *.json scenario file" in run.stderr
