"""A run writes its resolved configuration (config.json) and `--config` runs it again; the world's options on the
command line are derived from its typed configuration, each default written once (core/settings.py)."""
from __future__ import annotations

import json
import re

import pytest

from core.settings import entries
from sim.highway.config import WorldConfig
from sim.sidewalk.config import SidewalkConfig


def _drive(run_cli, out, *extra):
    return run_cli("drive", "--in-process", "--seconds", "0.5", "--cars", "2", "--out", str(out), *extra)


def test_a_run_writes_its_configuration_and_runs_again_from_it(run_cli, tmp_path):
    r = _drive(run_cli, tmp_path / "a", "--lanes", "2", "--seed", "5", "--set", "start_speed=12")
    assert r.returncode == 0, r.stderr
    saved = json.loads((tmp_path / "a" / "config.json").read_text())
    assert saved["world"] == "highway" and saved["model"] == "oracle" and saved["seconds"] == 0.5
    assert {k: saved["settings"][k] for k in ("lanes", "seed", "start_speed", "cars")} == \
        {"lanes": 2, "seed": 5, "start_speed": 12.0, "cars": 2}
    r = run_cli("drive", "--in-process", "--config", str(tmp_path / "a" / "config.json"), "--out", str(tmp_path / "b"))
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "b" / "config.json").read_text()) == saved
    first, again = (json.loads((tmp_path / d / "metrics.json").read_text()) for d in "ab")
    assert first["distance_m"] == again["distance_m"]          # the same run, driven again


def test_options_given_with_config_override_it(run_cli, tmp_path):
    assert _drive(run_cli, tmp_path / "a", "--lanes", "2").returncode == 0
    r = run_cli("drive", "--in-process", "--config", str(tmp_path / "a" / "config.json"), "--lanes", "3",
                "--seconds", "0.3", "--out", str(tmp_path / "b"))
    assert r.returncode == 0, r.stderr
    again = json.loads((tmp_path / "b" / "config.json").read_text())
    assert (again["settings"]["lanes"], again["settings"]["cars"], again["seconds"]) == (3, 2, 0.3)


@pytest.mark.parametrize("content, why", [
    ({"world": "highway", "settings": {"carz": 2}}, "unknown field 'carz' \\(did you mean 'cars'\\?\\)"),
    ({"world": "highway", "settings": {"cars": 999}}, "cars must be an integer from 0 to 300"),
    ({"world": "highway", "wheels": 4}, "unknown field 'wheels'"),
    ({"world": "sidewalk", "settings": {}}, "configures the sidewalk world"),
    ({"world": "highway", "seconds": -1}, "seconds must be a number above 0"),
    ([1, 2], "a run configuration is a JSON object"),
])
def test_a_bad_configuration_file_is_one_line_and_status_2(run_cli, tmp_path, content, why):
    f = tmp_path / "run.json"
    f.write_text(json.dumps(content))
    r = run_cli("drive", "--in-process", "--world", "highway", "--config", str(f), "--out", str(tmp_path / "o"))
    assert r.returncode == 2 and re.search(why, r.stderr) and r.stderr.count("\n") == 1, r.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("verb, world, config_type, paths, set_paths", [
    ("drive", "highway", WorldConfig, ("cars", "track", "seed"), ("start_speed", "renderer")),
    ("render", "highway", WorldConfig, (), ("camera.fov_deg", "mirror")),
    ("drive", "sidewalk", SidewalkConfig, ("rule", "mode"), ("path_width", "stereo.width")),
])
def test_the_help_shows_the_configurations_own_defaults(run_cli, verb, world, config_type, paths, set_paths):
    """The default in --help is the dataclass's, for a flag and for a setting given with --set: written once, so
    the two cannot disagree."""
    r = run_cli(verb, "--world", world, "--help")
    text = " ".join(r.stdout.split())
    for path in paths:
        e = entries(config_type)[path]
        assert re.search(re.escape(e.flag) + r" \S+ .*?\(default (\w+ )?" + re.escape(str(e.default)), text), path
    for path in set_paths:
        e = entries(config_type)[path]
        shown = "none" if e.default is None else str(e.default).lower() if isinstance(e.default, bool) else \
            str(e.default)
        assert f" {path}={shown}" in text, path


def test_help_lists_the_options_of_one_world_and_reads_every_worlds(run_cli, tmp_path):
    """drive --help lists the highway's options and says where the sidewalk's are; the sidewalk's are still read
    (and refused with the highway, naming the world they belong to)."""
    highway = run_cli("drive", "--help").stdout
    assert "--lanes" in highway and "--operation" not in highway
    assert "drivestudio drive --world sidewalk --help" in highway
    sidewalk = run_cli("drive", "--world", "sidewalk", "--help").stdout
    assert "--operation" in sidewalk and "--lanes" not in sidewalk and "--seed" in sidewalk
    r = run_cli("drive", "--operation", "expert", "--out", str(tmp_path / "o"))
    assert r.returncode == 2 and "--operation belongs to the sidewalk world, not to --world highway" in r.stderr
