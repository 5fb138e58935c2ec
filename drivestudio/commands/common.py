"""What the verbs share: choosing a world (`--world` plus that world's own options), output folders, models."""
from __future__ import annotations

import argparse
import re
import time
from pathlib import Path

from core.files import make_dir
from drivestudio import worlds
from drivestudio.errors import UsageError
from drivestudio.numbers import seed as seed_type

DEVICE = re.compile(r"(auto|cpu|cuda|cuda:\d{1,2}|mps)")


def add_world_options(p, verb: str, seed_default: int | None = 0, renderer: bool = True) -> None:
    """--world, --seed, --renderer, and every world's own options for `verb` (each in its own group)."""
    g = p.add_argument_group("world")
    g.add_argument("--world", default="highway", choices=worlds.names(), help="which world (default highway)")
    if seed_default is not None:
        g.add_argument("--seed", type=seed_type(), default=seed_default,
                       help=f"seed of the scene and the traffic (default {seed_default})")
    if renderer:
        g.add_argument("--renderer", choices=("tiny", "egl"), default="tiny", help="PyBullet renderer (default tiny)")
    options = worlds.WorldOptions(p, verb)
    for plugin in worlds.all_plugins():
        plugin.add_options(options)
    p.set_defaults(world_options=options)


def plugin_for(args) -> worlds.Plugin:
    """The selected world's plugin; options that only another world has are refused in one line."""
    plugin = worlds.get(args.world)
    options: worlds.WorldOptions = args.world_options
    for other in worlds.all_plugins():
        if other.name != plugin.name:
            given = [f for f in options.given(other.name, args) if not options.owns(plugin.name, f)]
            if given:
                raise UsageError(f"{', '.join(given)} belong{'s' if len(given) == 1 else ''} to the {other.name} "
                                 f"world, not to --world {plugin.name}")
    return plugin


def add_device_option(p, default: str = "cpu") -> None:
    p.add_argument("--device", default=default, type=device_type,
                   help=f"torch device: cpu, cuda, cuda:N or auto (default {default})")


def device_type(text: str) -> str:
    if not DEVICE.fullmatch(text):
        raise argparse.ArgumentTypeError(f"--device must be cpu, cuda, cuda:N or auto, got {text!r}")
    return text


def run_dir(out: str | None, prefix: str) -> Path:
    """The output folder (checked before any work, then created): --out, or runs/PREFIX-TIME."""
    return make_dir(Path(out) if out is not None else Path("runs") / f"{prefix}-{time.strftime('%Y%m%d-%H%M%S')}")
