"""Typed configurations (core/settings.py): each world's options have one default, unit and range, in its
configuration; the command line, Gymnasium and a run's config.json are derived from it."""
from __future__ import annotations

import math

import pytest

from core.settings import SettingError, as_json, assign, check, check_value, entries, from_json, with_values
from sim.highway.config import WorldConfig
from sim.sidewalk.config import SidewalkConfig

CONFIGS = (WorldConfig, SidewalkConfig)


@pytest.mark.parametrize("config_type", CONFIGS)
def test_every_default_is_within_its_own_range(config_type):
    assert check(config_type()) == config_type()
    for e in entries(config_type).values():
        if e.kind in (int, float) and e.default is not None:
            assert e.setting.low <= e.default <= e.setting.high, e.path


def test_nested_settings_are_found_by_path_with_their_flags_and_defaults():
    table = entries(WorldConfig)
    assert (table["camera.width"].flag, table["camera.width"].default) == ("--width", 280)
    assert (table["camera.fov_deg"].flag, table["camera.fov_deg"].default) == ("--fov", 60.0)
    assert (entries(SidewalkConfig)["stereo.width"].default, entries(SidewalkConfig)["stereo.height"].default) == \
        (336, 188)
    assert table["start_speed"].flag == "--start-speed" and table["start_speed"].setting.unit == "m/s"
    assert "vehicle" not in table and "dt" not in table     # fields that are not settings stay out


def test_the_highway_starts_at_the_speed_every_consumer_starts_at():
    """One default: drive, the benchmark's routes and Gymnasium all started the host at 15 m/s while the world's
    own default said 0."""
    from sim.highway.gym_env import DEFAULTS, HighwayEnv
    assert WorldConfig().start_speed == 15.0 and DEFAULTS.start_speed == 15.0 and WorldConfig().cars == 12
    assert HighwayEnv.__init__.__defaults__[HighwayEnv.__init__.__code__.co_varnames.index("cars") - 1] == 12


@pytest.mark.parametrize("path, value, why", [
    ("cars", 301, "must be an integer from 0 to 300, got 301"),
    ("cars", 2.5, "must be an integer, got 2.5"),
    ("cars", True, "must be an integer, got True"),
    ("lanes", 0, "must be an integer from 1 to 4"),
    ("start_speed", math.nan, "must be a finite number"),
    ("start_speed", 61.0, "from 0 to 60 m/s"),
    ("renderer", "ray", "invalid choice: 'ray' \\(choose from tiny, egl, numba, gl\\)"),
    ("mirror", "yes", "must be true or false"),
])
def test_a_value_out_of_its_setting_is_refused_in_one_line(path, value, why):
    with pytest.raises(SettingError, match=why) as e:
        check_value(entries(WorldConfig)[path], value)
    assert "\n" not in str(e.value)


def test_an_optional_setting_takes_none_and_a_required_one_does_not():
    table = entries(WorldConfig)
    assert check_value(table["lanes"], None) is None        # the track's own lane count
    with pytest.raises(SettingError, match="must be given"):
        check_value(table["cars"], None)


def test_with_values_replaces_nested_settings_and_leaves_the_rest():
    c = with_values(WorldConfig(), {"camera.width": 320, "cars": 3})
    assert (c.camera.width, c.camera.height, c.cars, c.track) == (320, 210, 3, "oval")
    assert WorldConfig().camera.width == 280     # a new configuration, the default untouched


@pytest.mark.parametrize("config_type", CONFIGS)
def test_a_configuration_reads_back_from_its_json(config_type):
    changed = with_values(config_type(), {"seed": 7})
    assert from_json(config_type(), as_json(changed), "run.json") == changed


def test_json_settings_are_checked_like_the_command_line():
    with pytest.raises(SettingError, match="run.json: unknown field 'carz' \\(did you mean 'cars'\\?\\)"):
        from_json(WorldConfig(), {"carz": 3}, "run.json")
    with pytest.raises(SettingError, match="run.json: cars must be an integer from 0 to 300"):
        from_json(WorldConfig(), {"cars": 1000}, "run.json")
    assert from_json(SidewalkConfig(), {"obstacles": "none"}, "run.json").obstacles == 0.0   # read as text is


def test_set_reads_each_kind_of_setting_from_text():
    """`--set NAME=VALUE`: numbers, true/false, none where None is a value, nested paths, a setting's own parser."""
    c = assign(WorldConfig(), ["start_speed=12.5", "mirror=true", "lanes=3", "camera.width=140", "track=procedural:4"])
    assert (c.start_speed, c.mirror, c.lanes, c.camera.width, c.track) == (12.5, True, 3, 140, "procedural:4")
    assert assign(c, ["mirror=no", "lanes=none"]).mirror is False and assign(c, ["lanes=None"]).lanes is None
    assert assign(SidewalkConfig(), ["path_width = 2"]).path_width == 2.0
    assert WorldConfig().mirror is False and WorldConfig().camera.width == 280     # the defaults are not touched


@pytest.mark.parametrize("pair, why", [
    ("start_speed", "--set takes NAME=VALUE, got 'start_speed'"),
    ("=3", "--set takes NAME=VALUE, got '=3'"),
    ("speed=3", "--set speed: no such setting (settings: track, lanes, cars"),
    ("start_speed=-1", "--set start_speed must be a number from 0 to 60 m/s, got -1.0"),
    ("start_speed=fast", "--set start_speed must be a number, got 'fast'"),
    ("cars=2.5", "--set cars must be an integer, got '2.5'"),
    ("mirror=perhaps", "--set mirror must be true or false, got 'perhaps'"),
    ("cars=none", "--set cars must be an integer, got 'none'"),
    ("renderer=vulkan", "--set renderer: invalid choice: 'vulkan' (choose from"),
])
def test_set_refuses_a_bad_pair_naming_it(pair, why):
    with pytest.raises(SettingError) as e:
        assign(WorldConfig(), [pair])
    assert str(e.value).startswith(why), str(e.value)
