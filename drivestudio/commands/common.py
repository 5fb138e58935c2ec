"""What the verbs share: choosing a world (`--world` plus that world's own options), output folders, models."""
from __future__ import annotations

import re
import time
from pathlib import Path

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
    for plugin in worlds.all_plugins():
        plugin.add_options(p, verb)


def plugin_for(args, verb: str):
    """The selected world's plugin; options of another world are refused in one line."""
    plugin = worlds.get(args.world)
    for other in worlds.all_plugins():
        if other.name != plugin.name:
            given = [f for f in other.options_given(args, verb) if f not in plugin._flags.get(verb, {})]
            if given:
                raise UsageError(f"{', '.join(given)} belong{'s' if len(given) == 1 else ''} to the {other.name} "
                                 f"world, not to --world {plugin.name}")
    return plugin


def add_device_option(p, default: str = "cpu") -> None:
    p.add_argument("--device", default=default, type=device_type,
                   help=f"torch device: cpu, cuda, cuda:N or auto (default {default})")


def device_type(text: str) -> str:
    import argparse
    if not DEVICE.fullmatch(text):
        raise argparse.ArgumentTypeError(f"--device must be cpu, cuda, cuda:N or auto, got {text!r}")
    return text


def check_device(name: str) -> str:
    """The device name, or UsageError when it names a GPU this machine does not have."""
    if name.startswith("cuda") or name == "mps":
        import torch
        if name.startswith("cuda") and not torch.cuda.is_available():
            raise UsageError(f"--device {name}: no CUDA device is available here")
        if name.startswith("cuda:") and int(name[5:]) >= torch.cuda.device_count():
            raise UsageError(f"--device {name}: this machine has {torch.cuda.device_count()} CUDA device(s)")
        if name == "mps" and not torch.backends.mps.is_available():
            raise UsageError("--device mps: no Apple GPU is available here")
    return name


def run_dir(out: str | None, prefix: str) -> Path:
    """The output folder (checked before any work, then created): --out, or runs/PREFIX-TIME."""
    from core.files import make_dir
    return make_dir(Path(out) if out is not None else Path("runs") / f"{prefix}-{time.strftime('%Y%m%d-%H%M%S')}")


def check_checkpoint_path(model: str) -> Path:
    path = Path(model)
    if not path.is_file():
        raise UsageError(f"--model must be a world's driver (oracle, expert) or a checkpoint file; no such file: "
                         f"{model}")
    return path


def load_predictor_for(model: str, world: str, device: str = "cpu"):
    """The predictor of a checkpoint, which must be a model of `world`."""
    check_checkpoint_path(model)
    from perception.predictor import load_predictor
    return load_predictor(model, device=check_device(device), world=world)
