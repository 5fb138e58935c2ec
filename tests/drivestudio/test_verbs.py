"""Verbs belong to their world: the generic verbs serve every world, a world's own verbs are its Plugin's and are
listed under it in --help; the command line's arguments object stays in the command layer."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from drivestudio import worlds
from drivestudio.cli import VERBS, build_parser

REPO = Path(__file__).resolve().parents[2]
LIBRARY = ("core", "sim", "perception", "controller", "shm_bridge", "drivestudio")


def _verbs() -> dict:
    return next(a for a in build_parser()._subparsers._group_actions if a.dest == "verb").choices  # type: ignore


def test_each_worlds_own_verbs_are_registered_and_listed_under_it():
    verbs = _verbs()
    text = build_parser().format_help()
    for plugin in worlds.all_plugins():
        for verb in plugin.verbs:
            assert verbs[verb].world == plugin.name
            assert re.search(rf"^\s+{verb}\s+\({plugin.name}\)", text, re.M), verb
        if plugin.verbs:
            assert re.search(rf"^  {plugin.name}:\s+{re.escape(', '.join(plugin.verbs))}$", text, re.M)
    assert {"benchmark", "recipe", "probe", "aggregate", "suite", "ppo"} <= set(worlds.get("highway").verbs)
    assert {"autonomy", "study"} == set(worlds.get("sidewalk").verbs)


def test_a_generic_verb_is_no_worlds_and_none_is_listed_twice():
    own = [v for p in worlds.all_plugins() for v in p.verbs]
    assert len(own) == len(set(own)) and not set(own) & set(VERBS)
    assert all(not hasattr(_verbs()[v], "world") for v in VERBS)


def test_no_module_below_the_command_layer_reads_the_command_line():
    """The library takes typed configurations and driver specs; argparse and its namespace stay in
    drivestudio/commands/ and drivestudio/cli.py."""
    offenders = []
    for package in LIBRARY:
        for path in (REPO / package).rglob("*.py"):
            rel = path.relative_to(REPO).as_posix()
            if rel.startswith("drivestudio/commands/") or rel == "drivestudio/cli.py":
                continue
            text = path.read_text()
            if re.search(r"^\s*(import argparse|from argparse)", text, re.M) or "getattr(args" in text:
                offenders.append(rel)
    assert offenders == []


def test_the_command_line_is_built_without_torch():
    """--help of every verb, the worlds' own included, pays only for what the verbs import at the top: no torch
    (a second of start-up and most of a GB)."""
    import subprocess
    import sys
    code = "import sys; from drivestudio.cli import build_parser; build_parser(); print('torch' in sys.modules)"
    r = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.strip() == "False", r.stderr


@pytest.mark.parametrize("world", ["highway", "sidewalk"])
def test_no_verb_shows_more_than_20_options_and_all_show_at_most_180(world):
    """The command line stays small: a setting beyond a verb's job is a `--set NAME=VALUE` of its configuration."""
    import argparse

    from drivestudio import cli
    cli.listed_world(["--world", world])
    try:
        parser = cli.build_parser()
    finally:
        cli.listed_world([])
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    shown = {verb: sum(1 for a in p._actions if a.option_strings and a.help != argparse.SUPPRESS
                       and "-h" not in a.option_strings) for verb, p in sub.choices.items()}
    assert max(shown.values()) <= 20, shown
    assert sum(shown.values()) <= 180, shown
