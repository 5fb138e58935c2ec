"""drivestudio train --data DIR --model NAME --out CKPT: fit a perception model of the dataset's world.

Its settings are perception/train_config.py's TrainConfig: the ones most runs give are flags, every other one is
`--set NAME=VALUE` (drivestudio/commands/run_settings.py). A family's trainer reads some of them, and one given that
it does not read is refused (perception/train.py's check_reads)."""
from __future__ import annotations

from pathlib import Path

from core import worlds
from core.files import check_output
from core.settings import entries
from drivestudio.checkpoints import check_checkpoint, check_device
from drivestudio.commands.run_settings import add_flags, add_set, resolve
from drivestudio.errors import UsageError
from perception.memory import check_batch
from perception.train_config import TrainConfig

REQUIRED = ("data", "model", "out")
# the settings most runs give, as flags (besides REQUIRED); every other one is --set NAME=VALUE
FLAGS = ("targets", "iterations", "epochs", "batch_size", "lr", "init", "weights", "device", "workers", "seed")

# written out: the registry imports torch, and the parser must not (every verb would start seconds slower)
FAMILIES = ("alexnet (AlexNet), vgg16 (VGG-16), gist (GIST + ridge), mobilenet (MobileNetV2 blocks, half resolution, "
            "optionally with earlier frames), z2color (Z2Color: MultiNet and its MTL baseline)")


def register(sub) -> None:
    p = sub.add_parser("train", help="train a model (AlexNet, VGG-16, GIST, Z2Color, ...) on a dataset",
                       description="Train a model of the dataset's world. Models: " + FAMILIES + ". The defaults are "
                                   "the papers' (for the highway Liu and Wang's: SGD with momentum and a stepped "
                                   "learning rate, the Euclidean loss on targets normalised to [0.1, 0.9]); GIST is "
                                   "fitted in closed form. Running the same command again continues from the "
                                   "checkpoint; loss curves are written beside it as CKPT.loss.csv and .png. Every "
                                   "other setting is --set NAME=VALUE: its help lists them with their defaults. A "
                                   "model's trainer reads some of them, and one it does not read is refused.")
    table = entries(TrainConfig)
    for name in REQUIRED:
        p.add_argument(table[name].flag, dest=name, required=True, metavar=name.upper(), help=table[name].setting.help)
    add_flags(p, TrainConfig, ("targets",))
    add_flags(p.add_mutually_exclusive_group(), TrainConfig, ("iterations", "epochs"))   # how long: one or the other
    add_flags(p, TrainConfig, [name for name in FLAGS if name not in ("targets", "iterations", "epochs")])
    add_set(p, TrainConfig, REQUIRED + FLAGS, "the training")
    p.set_defaults(func=run)


def check_inputs(cfg: TrainConfig) -> None:
    """The files and lists the settings name, opened or read now: refused in one line before any work."""
    if cfg.init is not None:   # a damaged or foreign checkpoint is refused before any work
        from perception.shards import Dataset  # lazy: pyarrow
        if not Path(cfg.init).is_file():
            raise UsageError(f"--init: no such file: {cfg.init}")
        check_checkpoint(cfg.init, Dataset(first_root(cfg.data)).world)
    if cfg.modes is not None and not [m for m in cfg.modes.split(",") if m.strip()]:
        raise UsageError(f"modes {cfg.modes!r} names no mode (leave it out for all the dataset has)")
    if cfg.weights and not Path(cfg.weights).is_file():
        raise UsageError(f"--weights: no such file: {cfg.weights}")
    if cfg.emphasis != 1:
        check_emphasis(first_root(cfg.data))
    if cfg.batch_size is not None:   # a batch whose inputs cannot fit is refused before anything is allocated
        check_batch_for(cfg, cfg.batch_size)


def check_batch_for(cfg: TrainConfig, batch_size: int) -> None:
    from perception.models import make_spec  # lazy: torch
    from perception.shards import Dataset  # lazy: pyarrow
    from perception.training import history_moment  # lazy: torch, pyarrow

    decl = Dataset(first_root(cfg.data)).declaration
    moment = history_moment(decl, cfg.history)
    spec = make_spec(cfg.model, decl, instants=None if moment is None else moment.instants)
    check_batch(batch_size, spec["input"])


def first_root(data: str) -> Path:
    """The first of --data's folders: Z2Color's trainer takes several, comma-separated (a data set and the
    corrections of later rounds; perception/multinet.py), all of one world and declaration."""
    return Path(next((r for r in str(data).split(",") if r), data))


def check_emphasis(data: Path) -> None:
    """UsageError unless the dataset's world declares decisive steps (emphasis has nothing to weigh else)."""
    from perception.shards import Dataset  # lazy: pyarrow

    world = Dataset(data).world
    if not worlds.get(world).decisive:
        raise UsageError(f"emphasis: the {world} world declares no decisive steps to emphasise")


def run(args) -> int:
    from perception.curves import curve_paths  # lazy: not for --help

    cfg = resolve(TrainConfig(), args, REQUIRED + FLAGS)
    check_device(cfg.device)
    check_output(cfg.out, (".pt", ".pth", ".ckpt"), "checkpoint")   # before any work, not after the fit
    for side in curve_paths(cfg.out):   # the loss curves written beside it
        check_output(side, None, "loss-curve file")

    from perception.train import check_reads, train  # lazy: torch, pyarrow

    check_reads(cfg)
    check_inputs(cfg)
    train(cfg)
    return 0
