"""What the verbs share: choosing a world (`--world` plus that world's own options), output folders, models."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from core.files import make_dir
from core.inputs import check_keys, read_json
from core.settings import check, entries, from_json
from drivestudio import worlds
from drivestudio.checkpoints import DEVICE
from drivestudio.commands.numbers import seed as seed_type
from drivestudio.commands.run_settings import defaults_text
from drivestudio.commands.world_options import WorldOptions, refuse_other_worlds
from drivestudio.errors import UsageError

HELP_WORLD = ["highway"]   # the world whose options --help lists (cli.main sets it from the command line's --world)


def add_world_options(p, verb: str, seed_default: int | None = 0) -> None:
    """--world and every world's options for `verb`: the settings of its configuration that the verb shows
    (drivestudio/commands/world_options.py) and its own options. Every world's options are read, but --help lists
    those of one world (`--world W --help` another's). --seed is added here for the verbs whose worlds are built
    otherwise (generate's plans)."""
    g = p.add_argument_group("world")
    g.add_argument("--world", default=None, choices=worlds.names(), help="which world (default highway, or the "
                   "--config file's)")
    plugins = worlds.all_plugins()
    settings = {pl.name: pl.verb_settings.get(verb, ()) for pl in plugins}
    shown = {path for paths in settings.values() for path in paths}
    if seed_default is not None and "seed" not in shown:
        g.add_argument("--seed", type=seed_type(), default=seed_default,
                       help=f"seed of the scene and the traffic (default {seed_default})")
    listed = HELP_WORLD[0] if HELP_WORLD[0] in settings else "highway"
    others = [pl.name for pl in plugins if pl.name != listed and settings[pl.name]]
    if others:
        p.epilog = "; ".join(f"the {w} world's options: {p.prog} --world {w} --help" for w in others)
    options = WorldOptions(p, verb)
    defaults: dict[str, dict] = {}
    for pl in plugins:
        for path in settings[pl.name]:
            e = entries(pl.config_type)[path]
            defaults.setdefault(e.flag, {})[pl.name] = e.default
    for pl in sorted(plugins, key=lambda pl: pl.name != listed):   # the listed world's flags first: shared ones show
        options.hidden = pl.name != listed
        group = options.group(f"{pl.name} world (--world {pl.name})")
        if settings[pl.name]:
            options.add_settings(pl.name, pl.config_type, settings[pl.name], group, defaults)
        pl.add_options(options)
    options.hidden = False
    add_set_option(g, worlds.get(listed), set(settings[listed]))
    p.set_defaults(world_options=options)


def add_set_option(group, plugin: worlds.Plugin, shown: set[str]) -> None:
    """--set NAME=VALUE: any setting of the world's configuration, those without a flag of their own listed."""
    group.add_argument("--set", action="append", metavar="NAME=VALUE",
                       help=f"a setting of the {plugin.name} world's configuration, repeatable; the others, with "
                            f"their defaults: {defaults_text(plugin.config_type, shown)} (docs/configuration.md)")


def plugin_for(args) -> worlds.Plugin:
    """The selected world's plugin (--world, the --config file's, or the highway); options that only another world
    has are refused in one line."""
    args.world = args.world or (run_config(args) or {}).get("world") or "highway"
    plugin = worlds.get(args.world)
    refuse_other_worlds(args.world_options, plugin, worlds.all_plugins(), args)
    return plugin


def world_config(plugin: worlds.Plugin, args):
    """The world's configuration: its defaults, then the --config file's settings, then those given on the command
    line, checked, with what they imply."""
    base = plugin.config_type()
    given = run_config(args)
    if given is not None:
        base = from_json(base, given.get("settings", {}), f"{args.config}: settings")
    return plugin.settle(check(args.world_options.config(plugin.name, base, args)))


RUN_KEYS = ("world", "settings", "model", "seconds", "realtime", "free_running", "device")


def add_config_option(p) -> None:
    p.add_argument("--config", metavar="RUN.json", help="run again as a run's config.json says (the run's folder "
                   "holds it); the options given here override it")


def run_config(args) -> dict | None:
    """The --config file (a run's config.json), read and checked once; None without --config."""
    path = getattr(args, "config", None)
    if path is None:
        return None
    if not hasattr(args, "_run_config"):
        data = read_json(path, "run configuration")
        if not isinstance(data, dict):
            raise UsageError(f"{path}: a run configuration is a JSON object")
        check_keys(data, RUN_KEYS, str(path), UsageError)
        if data.get("world") is not None and args.world is not None and data["world"] != args.world:
            raise UsageError(f"--world {args.world}: {path} configures the {data['world']} world")
        args._run_config = data
    return args._run_config


def run_seconds(args, default: float | None, high: float) -> float | None:
    """The run's simulated seconds: --seconds, else the --config file's (held to (0, high]), else `default`."""
    seconds = from_run(args, "seconds", default)
    if seconds is not None and (isinstance(seconds, bool) or not isinstance(seconds, (int, float))
                                or not 0 < seconds <= high):
        raise UsageError(f"{args.config}: seconds must be a number above 0 and at most {high:g}")
    return None if seconds is None else float(seconds)


def from_run(args, name: str, default):
    """An option of the run: as given on the command line, else the --config file's, else `default`."""
    value = getattr(args, name)
    if value not in (None, False):
        return value
    saved = (run_config(args) or {}).get(name)
    return default if saved is None else saved


def add_device_option(p, default: str | None = "cpu") -> None:
    """--device; with default None a run's --config file may name it (cpu otherwise)."""
    p.add_argument("--device", default=default, type=device_type,
                   help=f"torch device: cpu, cuda, cuda:N or auto (default {default or 'cpu'})")


def device_type(text: str) -> str:
    if not DEVICE.fullmatch(text):
        raise argparse.ArgumentTypeError(f"--device must be cpu, cuda, cuda:N or auto, got {text!r}")
    return text


def run_dir(out: str | None, prefix: str) -> Path:
    """The output folder (checked before any work, then created): --out, or runs/PREFIX-TIME."""
    return make_dir(Path(out) if out is not None else Path("runs") / f"{prefix}-{time.strftime('%Y%m%d-%H%M%S')}")
