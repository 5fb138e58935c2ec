"""Bad track and scenario input: one line naming the file and the field, refused before any work.

Each test here fails when the check it names is removed: the loaders are called directly, and a few cases go
through the real CLI (exit status 2, exactly one line on stderr, no traceback, quickly and in little memory).
"""
import json
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

import core.inputs as inputs
import sim.track.trackfile as trackfile
from core.inputs import MAX_JSON_BYTES, MAX_JSON_DEPTH, InputError, parse_json_text, read_json
from sim.highway.scenario import MAX_CARS, MAX_SEED, MAX_SPEED, ScenarioError, load_scenario, scenario_from_dict
from sim.track import TrackError, load_track, preset_names, track_from_spec, write_track
from sim.track.trackfile import MAX_ANGLE_DEG, MAX_ARC_RADIUS, MAX_SEGMENTS, MAX_STRAIGHT_LENGTH, MAX_TRACK_LENGTH

ROOT = Path(__file__).resolve().parents[2]


def straight(length):
    return {"type": "straight", "length": length}


def arc(radius, angle_deg=180, turn="left"):
    return {"type": "arc", "radius": radius, "angle_deg": angle_deg, "turn": turn}


def oval(length=400.0, radius=120.0, **extra):
    return {"name": "t-oval", "lanes": 3, "lane_width": 4.0,
            "segments": [straight(length), arc(radius), straight(length), arc(radius)], **extra}


def scenario(**over):
    return {"track": "oval", "ego": {"s": 100.0, "d": 0.0}, **over}


def write(path: Path, obj) -> Path:
    path.write_text(obj if isinstance(obj, str) else json.dumps(obj))
    return path


def refused(exc_type, call, *needles):
    """Run `call`, which must raise `exc_type` with a one-line message holding every needle; return it."""
    with pytest.raises(exc_type) as info:
        call()
    msg = str(info.value)
    assert "\n" not in msg and "\r" not in msg, msg
    for needle in needles:
        assert needle in msg, (needle, msg)
    return msg


@pytest.fixture
def no_track_built(monkeypatch):
    """Fail the test if a Track (whose validation samples the loop every 2 m) or any segment is built."""
    def boom(*a, **k):
        raise AssertionError("a track was built before its specs were checked")
    monkeypatch.setattr(trackfile, "Track", boom)
    monkeypatch.setattr(trackfile, "Straight", boom)
    monkeypatch.setattr(trackfile, "Arc", boom)


# --- 1. bounds on a track, checked on the specs before anything is built --------------------------------------------
def test_two_1e9_m_straights_are_refused_before_anything_is_built(no_track_built):
    t0 = time.perf_counter()
    refused(TrackError, lambda: track_from_spec(oval(length=1e9)), "segment 0", "'length'",
            f"at most {MAX_STRAIGHT_LENGTH:.0f} m", "1000000000")
    assert time.perf_counter() - t0 < 0.5


def test_total_length_is_bounded(no_track_built):
    spec = oval(length=MAX_STRAIGHT_LENGTH, radius=200.0)  # every segment in range, the sum over 20 km
    refused(TrackError, lambda: track_from_spec(spec), "track 't-oval'", "add up to",
            f"at most {MAX_TRACK_LENGTH:.0f} m")


def test_segment_count_is_bounded(no_track_built):
    spec = oval()
    spec["segments"] = [straight(1.0)] * (MAX_SEGMENTS + 1)
    refused(TrackError, lambda: track_from_spec(spec), f"{MAX_SEGMENTS + 1} segments", f"at most {MAX_SEGMENTS}")


@pytest.mark.parametrize("segment, field, allowed", [
    (straight(MAX_STRAIGHT_LENGTH + 1), "'length'", "positive and at most 10000 m"),
    (straight(-3), "'length'", "positive"),
    (straight(0), "'length'", "positive"),
    (arc(MAX_ARC_RADIUS + 1, 1), "'radius'", "at most 10000 m"),
    (arc(-50), "'radius'", "positive"),
    (arc(100, MAX_ANGLE_DEG + 1), "'angle_deg'", "at most 360 degrees"),
    (arc(100, 0), "'angle_deg'", "positive"),
    (arc(100, -90), "'angle_deg'", "positive"),
    (arc(100, 90, "up"), "'turn'", "'left' or 'right'"),
    ({"type": "zigzag"}, "'type'", "'straight' or 'arc'"),
    ({"type": ["straight"], "length": 5}, "'type'", "'straight' or 'arc'"),
    ({"type": "arc", "radius": 100, "angle_deg": 90, "turn": ["left"]}, "'turn'", "'left' or 'right'"),
])
def test_each_segment_field_is_bounded(no_track_built, segment, field, allowed):
    spec = oval()
    spec["segments"] = [straight(100), segment]
    refused(TrackError, lambda: track_from_spec(spec), "segment 1", field, allowed)


def test_an_arc_too_tight_for_the_road_is_refused_before_building(no_track_built):
    spec = oval(radius=1e-300)
    refused(TrackError, lambda: track_from_spec(spec), "segment 1", "too tight", "need at least 18.0 m")


def test_the_limits_hold_every_preset_and_procedural_track():
    for name in preset_names():
        for lanes in (1, 2, 3, 4):
            tr = load_track(name, lanes=lanes)
            assert tr.length <= MAX_TRACK_LENGTH and len(tr.segments) <= MAX_SEGMENTS
    for seed in range(31):
        for lanes in (1, 2, 3, 4):
            load_track(f"procedural:{seed}", lanes=lanes)
    load_track(str(ROOT / "docs" / "examples" / "kidney.json"))
    for name in ("three-lane", "on-marking", "own-track"):
        load_scenario(ROOT / "docs" / "examples" / f"{name}.json")


def test_a_track_just_inside_the_limits_loads_quickly():
    # 2 x 9.4 km straights: 19.4 km, the longest loop of this shape the limits allow, with 4 lanes
    spec = oval(length=9400.0, radius=100.0)
    t0 = time.perf_counter()
    tr = track_from_spec(spec, lanes=4)
    assert tr.length == pytest.approx(18800 + 200 * math.pi)
    assert time.perf_counter() - t0 < 1.5


def test_a_written_track_reads_back(tmp_path):
    tr = load_track("mixed", lanes=2)
    write_track(tr, tmp_path / "m.json")
    assert load_track(str(tmp_path / "m.json")).length == pytest.approx(tr.length)


def test_the_overlap_check_still_finds_a_crossing():
    spec = {"name": "double", "segments": [arc(50, 360), arc(80, 360)]}
    refused(TrackError, lambda: track_from_spec(spec, lanes=2), "runs into itself")


def test_the_procedural_seed_is_bounded():
    refused(TrackError, lambda: load_track("procedural:" + "9" * 30), "procedural", "from 0 to")
    refused(TrackError, lambda: load_track("procedural:" + "9" * 5000), "procedural", "from 0 to")  # int() refuses
    refused(TrackError, lambda: load_track("procedural:\u00b2"), "procedural", "integer")  # a digit, not 0-9
    refused(TrackError, lambda: load_track("procedural:-1"), "procedural", "integer")


# --- 2. the bounded JSON reader -------------------------------------------------------------------------------------
def finishes(call, seconds=5.0):
    """Run `call` in a thread; fail (instead of hanging the suite) if it does not finish in time."""
    out = {}

    def run():
        try:
            out["value"] = call()
        except BaseException as e:  # noqa: BLE001 - handed to the test
            out["error"] = e
    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), "the reader blocked"
    if "error" in out:
        raise out["error"]
    return out.get("value")


def test_dev_zero_is_refused_without_reading_it():
    refused(InputError, lambda: finishes(lambda: read_json("/dev/zero")), "/dev/zero", "character device")
    refused(ScenarioError, lambda: finishes(lambda: load_scenario("/dev/zero")), "/dev/zero", "not a scenario file")


def test_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    refused(InputError, lambda: finishes(lambda: read_json(fifo)), str(fifo), "FIFO")
    refused(ScenarioError, lambda: finishes(lambda: load_scenario(fifo)), str(fifo), "FIFO")


def test_a_fifo_swapped_in_after_the_check_cannot_block(tmp_path, monkeypatch):
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    regular = os.stat(__file__)
    monkeypatch.setattr(inputs.os, "stat", lambda path: regular)  # as if the FIFO replaced a file meanwhile
    refused(InputError, lambda: finishes(lambda: read_json(fifo)), str(fifo), "FIFO")


def test_a_directory_is_refused(tmp_path):
    d = tmp_path / "dir.json"
    d.mkdir()
    refused(TrackError, lambda: load_track(str(d)), str(d), "directory")
    refused(ScenarioError, lambda: load_scenario(d), str(d), "directory")


def test_a_file_over_the_size_limit_is_refused_unread(tmp_path, monkeypatch):
    big = tmp_path / "big.json"
    with open(big, "wb") as f:
        f.truncate(MAX_JSON_BYTES + 1)  # sparse: nothing to write, nothing should be read
    reads = []
    monkeypatch.setattr(inputs.os, "read", lambda fd, n: reads.append(n) or b"")
    refused(InputError, lambda: read_json(big), str(big), f"at most {MAX_JSON_BYTES} bytes")
    assert reads == []


def test_no_more_than_the_limit_is_read_when_the_size_lies(tmp_path, monkeypatch):
    big = tmp_path / "growing.json"
    big.write_text("[" + "0," * MAX_JSON_BYTES + "0]")
    real = os.fstat

    def fstat_says_empty(fd):  # a file that grows, or a /proc file, reports a size it does not keep
        st = list(real(fd))
        st[6] = 0
        return os.stat_result(st)
    monkeypatch.setattr(inputs.os, "fstat", fstat_says_empty)
    reads = []
    real_read = os.read
    monkeypatch.setattr(inputs.os, "read", lambda fd, n: reads.append(n) or real_read(fd, n))
    refused(InputError, lambda: read_json(big), str(big), f"at most {MAX_JSON_BYTES} bytes")
    assert sum(reads) <= MAX_JSON_BYTES + 1


def test_text_that_is_not_utf8_is_refused(tmp_path):
    path = tmp_path / "latin1.json"
    path.write_bytes('{"name": "Fahrbahn über"}'.encode("latin-1"))
    refused(InputError, lambda: read_json(path), str(path), "not UTF-8", "0xfc")


def test_a_utf8_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "bom.json"
    path.write_bytes(b"\xef\xbb\xbf" + json.dumps(oval()).encode())
    assert load_track(str(path)).name == "t-oval"


@pytest.mark.parametrize("text", ["[" * 200_000 + "]" * 200_000, '{"a":' * 150_000 + "1" + "}" * 150_000,
                                  "[" * (MAX_JSON_DEPTH + 1) + "]" * (MAX_JSON_DEPTH + 1)])
def test_deep_nesting_is_refused_without_recursion(tmp_path, text):
    path = write(tmp_path / "deep.json", text)
    refused(InputError, lambda: read_json(path), str(path), f"nested more than {MAX_JSON_DEPTH} levels")


def test_nesting_up_to_the_limit_is_parsed():
    obj = parse_json_text("[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH)
    depth = 0
    while isinstance(obj, list):
        depth += 1
        obj = obj[0] if obj else None
    assert depth == MAX_JSON_DEPTH


@pytest.mark.parametrize("text, where, what", [
    ('{"track": "oval", "ego": {"s": NaN, "d": 0}}', "ego.s", "NaN"),
    ('{"track": "oval", "ego": {"s": 0, "d": Infinity}}', "ego.d", "Infinity"),
    ('{"track": "oval", "ego": {"s": 0, "d": 0}, "cars": [{"s": 1, "d": 0, "speed": -Infinity}]}',
     "cars[0].speed", "-Infinity"),
    ('{"track": "oval", "ego": {"s": 1e999, "d": 0}}', "ego.s", "1e999"),
    ('{"track": "oval", "seed": ' + "7" * 40 + ', "ego": {"s": 0, "d": 0}}', "seed", "at most 30 digits"),
    ('{"track": "oval", "ego": {"s": 0, "d": 0}, "ego": {"s": 5, "d": 0}}', "'ego'", "twice"),
])
def test_numbers_json_should_not_hold_are_refused_by_the_parser(tmp_path, text, where, what):
    path = write(tmp_path / "s.json", text)
    refused(ScenarioError, lambda: load_scenario(path), str(path), where, what)


def test_empty_and_malformed_files(tmp_path):
    refused(InputError, lambda: read_json(write(tmp_path / "e.json", "")), "empty")
    refused(InputError, lambda: read_json(write(tmp_path / "m.json", "{not json")), "malformed JSON at line 1")


def test_odd_file_names_stay_on_one_line(tmp_path):
    odd = tmp_path / "two\nlines.json"
    refused(TrackError, lambda: load_track(str(odd)), "no such file", "two\\nlines")
    refused(TrackError, lambda: load_track("nul\x00.json"), "not a valid file name")
    refused(TrackError, lambda: load_track("x" * 5000), "unknown track preset")  # never looked up as a file


# --- 3. unknown fields ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("spec, where, key, hint", [
    (oval(lenght=5), "track", "'lenght'", None),
    (oval(lanewidth=4.0), "track", "'lanewidth'", "lane_width"),
    (dict(oval(), segments=[{"type": "straight", "lenght": 400}]), "segment 0", "'lenght'", "length"),
    (dict(oval(), segments=[{"type": "arc", "radius": 100, "angle": 180, "turn": "left"}]), "segment 0", "'angle'",
     "angle_deg"),
    (dict(oval(), segments=[{"type": "straight", "length": 100, "radius": 5}]), "segment 0", "'radius'", None),
    (dict(oval(), segments=[{"typ": "straight", "length": 100}]), "segment 0", "'typ'", "type"),
])
def test_unknown_track_fields_are_named(spec, where, key, hint):
    msg = refused(TrackError, lambda: track_from_spec(spec), where, key, "unknown field")
    if hint:
        assert f"did you mean '{hint}'?" in msg


@pytest.mark.parametrize("obj, where, key, hint", [
    (scenario(car=[]), "scenario", "'car'", "cars"),
    (scenario(sed=3), "scenario", "'sed'", "seed"),
    (scenario(ego={"s": 0, "d": 0, "sped": 3}), "ego", "'sped'", "speed"),
    (scenario(ego={"s": 0, "d": 0, "yaw": 0.1}), "ego", "'yaw'", None),
    (scenario(cars=[{"s": 0, "d": 0}, {"s": 5, "d": 0, "heading": 0.1}]), "car 1", "'heading'", None),
])
def test_unknown_scenario_fields_are_named(obj, where, key, hint):
    msg = refused(ScenarioError, lambda: scenario_from_dict(obj), where, key, "unknown field")
    if hint:
        assert f"did you mean '{hint}'?" in msg


def test_a_typo_in_a_scenario_file_names_the_file(tmp_path):
    path = write(tmp_path / "typo.json", scenario(ego={"s": 0, "d": 0, "sped": 3}))
    refused(ScenarioError, lambda: load_scenario(path), str(path), "ego", "'sped'", "did you mean 'speed'?")


# --- 4. numbers where they belong, within range ---------------------------------------------------------------------
@pytest.mark.parametrize("obj, needles", [
    (scenario(ego={"s": True, "d": 0}), ["ego", "'s'", "a number"]),
    (scenario(ego={"s": "10", "d": 0}), ["ego", "'s'", "a number"]),
    (scenario(ego={"s": float("nan"), "d": 0}), ["ego", "'s'", "a number"]),
    (scenario(ego={"s": 0, "d": float("inf")}), ["ego", "'d'", "a number"]),
    (scenario(ego={"s": 0, "d": 0, "speed": -1}), ["ego", "'speed'", "from 0 to 100 m/s"]),
    (scenario(ego={"s": 0, "d": 0, "speed": MAX_SPEED + 1}), ["ego", "'speed'", "from 0 to 100 m/s"]),
    (scenario(ego={"s": 0, "d": 0, "heading": 7}), ["ego", "'heading'", "rad"]),
    (scenario(ego={"s": 1e12, "d": 0}), ["ego", "'s'", "beyond the track"]),
    (scenario(ego={"s": -5000, "d": 0}), ["ego", "'s'", "beyond the track"]),
    (scenario(ego={"s": 0, "d": 1e12}), ["ego", "d = 1e+12 m is off the road"]),
    (scenario(cars=[{"s": 0, "d": 0, "speed": -5}]), ["car 0", "'speed'", "from 0 to 100 m/s"]),
    (scenario(cars=[{"s": 0, "d": 0, "speed": 1e6}]), ["car 0", "'speed'", "from 0 to 100 m/s"]),
    (scenario(cars=[{"s": 1e12, "d": 0}]), ["car 0", "'s'", "beyond the track"]),
    (scenario(cars=[{"s": 0, "d": "left"}]), ["car 0", "'d'", "a number"]),
    (scenario(cars=[{"s": 10.0 * i, "d": 0} for i in range(MAX_CARS + 1)]), ["'cars'", f"at most {MAX_CARS}"]),
    (scenario(seed=-1), ["'seed'", f"an integer from 0 to {MAX_SEED}"]),
    (scenario(seed=MAX_SEED + 1), ["'seed'", f"an integer from 0 to {MAX_SEED}"]),
    (scenario(seed=True), ["'seed'", "an integer"]),
    (scenario(seed=1.5), ["'seed'", "an integer"]),
    (scenario(lanes=7), ["lanes must be an integer from 1 to 4"]),
    (scenario(lanes="3"), ["lanes must be an integer from 1 to 4"]),
    (scenario(track=5), ["'track'"]),
])
def test_bad_numbers_name_the_field_and_the_range(obj, needles):
    refused(ScenarioError, lambda: scenario_from_dict(obj), *needles)


def test_fields_in_range_are_accepted():
    sc = scenario_from_dict(scenario(seed=MAX_SEED, ego={"s": -10.0, "d": 0.0, "heading": -math.pi, "speed": 100},
                                     cars=[{"s": 1900, "d": 4.0, "speed": 100.0}, {"s": -1900, "d": -4.0}]))
    assert sc.seed == MAX_SEED and sc.ego.s == pytest.approx(sc.track.length - 10.0)
    assert [c.s for c in sc.cars] == pytest.approx([1900, sc.track.length - 1900])


@pytest.mark.parametrize("bad, needles", [
    ({"lanes": True}, ["lanes must be"]), ({"lane_width": float("nan")}, ["lane_width"]),
    ({"lane_width": "4"}, ["lane_width"]), ({"name": ""}, ["'name'"]), ({"name": "a\nb"}, ["'name'", "'a\\nb'"]),
    ({"name": "x" * 65}, ["'name'", "at most 64"]),
    ({"segments": [straight(True)]}, ["'length'", "a positive number"]),
    ({"segments": [straight("400")]}, ["'length'", "a positive number"]),
    ({"segments": [straight(float("inf"))]}, ["'length'"]),
    ({"segments": [arc(float("nan"))]}, ["'radius'"]),
    ({"segments": "all of them"}, ["'segments'", "non-empty list"]),
])
def test_bad_track_numbers_and_names(bad, needles):
    refused(TrackError, lambda: track_from_spec(dict(oval(), **bad)), *needles)


# --- 5. one line naming the file ------------------------------------------------------------------------------------
def test_a_bad_track_file_is_named_through_its_scenario(tmp_path):
    write(tmp_path / "long.json", oval(length=1e9))
    path = write(tmp_path / "s.json", scenario(track="long.json"))
    long = str(tmp_path / "long.json")
    refused((ScenarioError, TrackError), lambda: load_scenario(path), str(path), long, "segment 0", "'length'")
    refused(TrackError, lambda: load_track(str(tmp_path / "long.json")), str(tmp_path / "long.json"), "'length'")


# --- the real CLI ---------------------------------------------------------------------------------------------------
def probe(path, timeout=60):
    """`drivestudio probe PATH` in a wrapper that reports the CLI's CPU time and peak memory; (status, stderr, CPU
    seconds, peak MiB). CPU time, not wall time: a busy machine must not fail the test.

    The wrapper kills the CLI after `timeout` seconds (status 124), so that a read that blocks cannot hang the suite.
    """
    wrapper = ("import resource, subprocess, sys\n"
               "try:\n"
               "    r = subprocess.run([sys.executable, '-m', 'drivestudio', 'probe', sys.argv[1]],"
               " capture_output=True, text=True, timeout=float(sys.argv[2]))\n"
               "    rc, err = r.returncode, r.stderr\n"
               "except subprocess.TimeoutExpired:\n"
               "    rc, err = 124, 'timed out'\n"
               "u = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
               "sys.stdout.write(f'{rc} {u.ru_utime + u.ru_stime:.3f} {u.ru_maxrss}\\n')\n"
               "sys.stderr.write(err)\n")
    r = subprocess.run([sys.executable, "-c", wrapper, str(path), str(timeout)], capture_output=True, text=True,
                       cwd=ROOT, timeout=timeout + 30)
    rc, seconds, peak_kib = r.stdout.split()
    return int(rc), r.stderr, float(seconds), int(peak_kib) / 1024


def assert_one_line(rc, stderr, *needles):
    assert rc == 2, stderr
    assert stderr.count("\n") == 1 and stderr.startswith("drivestudio probe: error: "), stderr
    assert "Traceback" not in stderr
    for needle in needles:
        assert needle in stderr, (needle, stderr)


def test_cli_refuses_a_1e9_m_track_at_once_and_in_little_memory(tmp_path):
    write(tmp_path / "huge.json", {"name": "huge", "segments": [straight(1e9), arc(100), straight(1e9), arc(100)]})
    path = write(tmp_path / "s.json", scenario(track="huge.json"))
    rc, err, seconds, peak_mib = probe(path)
    assert_one_line(rc, err, "huge.json", "segment 0", "'length'", "at most 10000 m")
    assert seconds < 10 and peak_mib < 1024, (seconds, peak_mib)  # was 24 GB until killed
    t0 = time.perf_counter()
    with pytest.raises((ScenarioError, TrackError)):
        load_scenario(path)
    assert time.perf_counter() - t0 < 0.5


@pytest.mark.parametrize("make, needles", [
    (lambda d: Path("/dev/zero"), ["/dev/zero", "character device"]),
    (lambda d: (os.mkfifo(d / "p.json"), d / "p.json")[1], ["p.json", "FIFO"]),
    (lambda d: (d / "dir").mkdir() or d / "dir", ["directory"]),
    (lambda d: write(d / "deep.json", "[" * 200_000 + "]" * 200_000), ["nested more than 32 levels"]),
    (lambda d: (d / "l.json").write_bytes(b'{"track": "\xff"}') and d / "l.json", ["not UTF-8"]),
    (lambda d: write(d / "n.json", '{"track": "oval", "ego": {"s": NaN, "d": 0}}'), ["ego.s", "NaN"]),
    (lambda d: write(d / "t.json", scenario(ego={"s": 0, "d": 0, "sped": 3})), ["'sped'", "did you mean 'speed'?"]),
])
def test_cli_gives_one_line_and_status_2(tmp_path, make, needles):
    path = make(tmp_path)
    rc, err, seconds, _ = probe(path, timeout=30)
    assert_one_line(rc, err, *needles)
