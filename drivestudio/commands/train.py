"""drivestudio train --data DIR --model NAME --out CKPT: fit a perception model of the dataset's world."""
from __future__ import annotations

from pathlib import Path

from core import worlds
from core.files import check_output
from drivestudio.checkpoints import check_checkpoint, check_device
from drivestudio.commands.common import add_device_option
from drivestudio.commands.numbers import count, finite, positive, seed
from drivestudio.errors import UsageError
from perception.memory import check_batch

# The options each trainer reads (perception/train_sgd.py, multinet.py, gist_fit.py); any other one given with a
# family of that trainer would be ignored, so it is refused instead. Family-specific ones are checked in run().
TRAINER_OPTIONS = ("iterations", "epochs", "batch_size", "lr", "lr_step", "lr_gamma", "optimizer", "loss",
                   "ema", "weight_decay", "amp", "workers", "val_every", "val_frames", "checkpoint_every", "weights",
                   "regressor", "modes", "mtl", "trials", "mode_moments", "history", "init", "channels_last", "cache",
                   "unfreeze", "batch_norm", "emphasis", "steer_share")
APPLIES = {
    "sgd": set(TRAINER_OPTIONS) - {"regressor", "modes", "mtl", "trials", "mode_moments", "steer_share"},
    "multinet": {"epochs", "batch_size", "lr", "optimizer", "modes", "mtl", "trials", "mode_moments", "init", "amp",
                 "steer_share"},
    "closed-form": {"regressor", "val_frames"},
}
_DEFAULTS: dict[str, object] = {}

FAMILIES = ("alexnet (AlexNet), vgg16 (VGG-16), gist (GIST + ridge), mobilenet (MobileNetV2 blocks, half resolution, "
            "optionally with earlier frames), z2color (Z2Color: MultiNet and its MTL baseline)")


# long but declarative: one add_argument per option, each with its help; splitting it would only scatter them
def register(sub) -> None:
    lines = FAMILIES   # the registry imports torch: the parser must not (every verb would start seconds slower)
    p = sub.add_parser("train", help="train a model (AlexNet, VGG-16, GIST, Z2Color, ...) on a dataset",
                       description="Train a model of the dataset's world. Models: " + lines + ". The highway's "
                                   "defaults are Liu and Wang's: SGD momentum 0.9, lr x0.9 every 1000 iterations, "
                                   "AlexNet lr 1e-2 batch 15 for 10,000 iterations, VGG-16 (conv frozen) lr 1e-4 "
                                   "batch 10 for 15,000; Euclidean loss on targets normalised to [0.1, 0.9]. GIST is "
                                   "fitted in closed form. Running the same command again continues from the "
                                   "checkpoint; loss curves are written beside it as CKPT.loss.csv and .png.")
    p.add_argument("--data", required=True, help="dataset folder written by `drivestudio generate` (for --model "
                                                "z2color: several, comma-separated)")
    p.add_argument("--model", required=True, help="the model family: one that fits the dataset's world")
    p.add_argument("--out", required=True, help="checkpoint file to write (and to continue from if it exists)")
    p.add_argument("--targets", help="comma-separated labels to learn (default: the world's); +NAME adds to the "
                                     "default, e.g. +fast,+lanes_left")
    p.add_argument("--labels", metavar="SET", help="a named label set of the dataset's world as the targets; "
                                                   "highway: paper (the default, the paper's 13) or extended (the "
                                                   "14, lanes_left and the cars beside and behind: "
                                                   "docs/affordances.md)")
    length = p.add_mutually_exclusive_group()
    length.add_argument("--iterations", type=count(1, 10**8),
                        help="training iterations (default 10000 alexnet, 15000 vgg16)")
    length.add_argument("--epochs", type=positive(10**5), help="passes over the training split")
    p.add_argument("--batch-size", type=count(1, 65536), help="samples per iteration (default "
                                                                              "15 alexnet, 10 vgg16)")
    p.add_argument("--lr", type=positive(100.0), help="initial learning rate (default 1e-2 alexnet, "
                                                              "1e-4 vgg16)")
    p.add_argument("--lr-step", type=count(1, 10**8), default=1000,
                   help="iterations between learning-rate decays (1000)")
    p.add_argument("--lr-gamma", type=positive(1.0), default=0.9,
                   help="learning-rate decay factor (0.9)")
    p.add_argument("--optimizer", choices=("sgd", "adam", "adadelta"), default=None,
                   help="sgd with momentum 0.9 (default for the highway models), adam, adadelta (MultiNet's)")
    # the names of perception/training.py's LOSSES, written out: the parser must not import torch
    p.add_argument("--loss", choices=("euclidean", "l1"), default=None,
                   help="euclidean (the papers': half the squared error; the default but for mobilenet) or l1 (the "
                        "absolute error the MAE reports measure, every indicator pulling alike; mobilenet's "
                        "default); a continued or --init run keeps its checkpoint's")
    p.add_argument("--ema", metavar="DECAY", type=finite(0.0, 0.9999), default=None,
                   help="save and validate the moving average of the weights, decay per step DECAY (0.995: about "
                        "the last 200 steps; 0: none; default 0.995 mobilenet, else 0)")
    p.add_argument("--weight-decay", type=finite(0.0, 1.0), default=0.0,
                   help="L2 weight decay (default 0)")
    add_device_option(p, "auto")
    p.add_argument("--no-amp", dest="amp", action="store_false",
                   help="train in float32 throughout: no mixed precision on CUDA, no bfloat16 autocast for Z2Color "
                        "(used by default only where the processor computes bfloat16 natively)")
    p.add_argument("--workers", type=count(0, 64), default=1, help="processes decoding frames (1)")
    p.add_argument("--val-every", type=count(1, 10**8), default=500,
                   help="iterations between validations and checkpoints")
    p.add_argument("--val-frames", type=count(1, 10**7), default=1000,
                   help="validation samples used (default 1000)")
    p.add_argument("--checkpoint-every", type=positive(10**6), default=300.0,
                   help="also save at least every this many seconds (default 300)")
    p.add_argument("--unfreeze", action="store_true", help="vgg16: train the convolutional layers too")
    p.add_argument("--batch-norm", action="store_true", help="vgg16: use VGG-16 with batch normalisation")
    p.add_argument("--weights", help="torchvision ImageNet state dict for the convolutional trunk (e.g. "
                   "vgg16-397923af.pth, alexnet-owt-7be5be79.pth) that you already have; nothing is downloaded")
    p.add_argument("--fast", action="store_true", help="highway: also predict the 14th indicator, fast")
    p.add_argument("--lanes-left", action="store_true", help="highway: also predict lanes_left (Liu and Wang's "
                                                              "proposed fix for off-by-one-lane errors)")
    p.add_argument("--regressor", choices=("ridge", "rbf"), default="ridge",
                   help="gist: linear ridge (default) or RBF kernel ridge (random Fourier features)")
    p.add_argument("--modes", help="z2color: behavioural modes to train on (default: all the dataset has)")
    p.add_argument("--mtl", metavar="MODE", help="z2color: the MTL baseline, without the modal input, trained on "
                                                 "one mode's data")
    p.add_argument("--trials", type=count(1, 100), default=1,
                   help="z2color: repeat training with fresh seeds, for curves with confidence intervals (default 1)")
    p.add_argument("--mode-moments", type=count(1, 10**9), metavar="N",
                   help="z2color: an epoch draws at most N moments of each behavioural mode, afresh each epoch "
                        "(default: one pass over the training split); short fine-tuning on a growing data set")
    p.add_argument("--steer-share", type=finite(0.0, 1.0), default=0.0, metavar="F",
                   help="z2color: a share F of each mode's draws comes from its steering moments (the actuated "
                        "steering at least 0.1 from straight ahead), the rest from all of them (default 0; the "
                        "MultiNet authors' code draws half and half; docs/sidewalk.md)")
    p.add_argument("--history", type=count(0, 2), default=0,
                   help="mobilenet: also read the previous 1 or 2 frames (0.1 s apart) beside the current one "
                        "(default 0)")
    p.add_argument("--emphasis", type=count(1, 100), default=1, metavar="W",
                   help="an epoch shows the world's decisive steps W times, every other step once (default 1); "
                        "highway: the frames with a car closer than 20 m ahead in the host's lane (the follow law "
                        "brakes on it) or a neighbouring one (the Chen controller's lane changes are decided on it; "
                        "docs/aggregation.md)")
    p.add_argument("--init", metavar="CKPT", help="start from this checkpoint's weights (same family, world and "
                                                  "targets): fine-tuning, aggregation rounds, the correction rounds "
                                                  "of `study` and `autonomy --rounds`")
    p.add_argument("--no-channels-last", dest="channels_last", action="store_false",
                   help="keep weights and inputs contiguous on the CPU (channels-last is faster with oneDNN; for "
                        "comparison)")
    p.add_argument("--no-cache", dest="cache", action="store_false",
                   help="decode every frame every epoch instead of once into DATA/.frames (the frame cache)")
    p.add_argument("--seed", type=seed(), default=0, help="seed of initialisation and data order")
    p.set_defaults(func=run)
    _DEFAULTS.update({a.dest: a.default for a in p._actions})


def check_applies(args, trainer: str) -> None:
    """UsageError naming the options given (other than their defaults) that the family's trainer does not read."""
    given = [o for o in TRAINER_OPTIONS if o not in APPLIES[trainer] and getattr(args, o) != _DEFAULTS.get(o)]
    if given:
        flags = ", ".join(_flag(o) for o in given)
        takes = ", ".join(_flag(o) for o in TRAINER_OPTIONS if o in APPLIES[trainer])
        raise UsageError(f"{flags} {'does' if len(given) == 1 else 'do'} not apply to --model {args.model} "
                         f"({trainer} training takes {takes})")


def check_batch_for(args) -> None:
    from perception.models import make_spec  # lazy: torch
    from perception.shards import Dataset  # lazy: pyarrow
    from perception.training import history_moment  # lazy: torch, pyarrow

    decl = Dataset(first_root(args.data)).declaration
    moment = history_moment(decl, args.history)
    spec = make_spec(args.model, decl, instants=None if moment is None else moment.instants)
    check_batch(args.batch_size, spec["input"])


def first_root(data: str) -> Path:
    """The first of --data's folders: Z2Color's trainer takes several, comma-separated (a data set and the
    corrections of later rounds; perception/multinet.py), all of one world and declaration."""
    return Path(next((r for r in str(data).split(",") if r), data))


def check_emphasis(data: Path) -> None:
    """UsageError unless the dataset's world declares decisive steps (`--emphasis` has nothing to weigh else)."""
    from perception.shards import Dataset  # lazy: pyarrow

    world = Dataset(data).world
    if not worlds.get(world).decisive:
        raise UsageError(f"--emphasis: the {world} world declares no decisive steps to emphasise")


def _flag(dest: str) -> str:
    return {"amp": "--no-amp", "channels_last": "--no-channels-last", "cache": "--no-cache"}.get(
        dest, "--" + dest.replace("_", "-"))


def run(args) -> int:
    from perception.curves import curve_paths  # lazy: not for --help
    from perception.models import family  # lazy: torch

    check_device(args.device)
    check_output(args.out, (".pt", ".pth", ".ckpt"), "checkpoint")   # before any work, not after the fit
    for side in curve_paths(args.out):   # the loss curves written beside it
        check_output(side, None, "loss-curve file")
    fam = family(args.model)
    check_applies(args, fam.trainer)
    if args.model != "vgg16" and (args.unfreeze or args.batch_norm):
        raise UsageError("--unfreeze and --batch-norm go with --model vgg16")
    if args.model == "gist" and args.weights:
        raise UsageError("--weights goes with --model vgg16 or alexnet")
    if args.model != "gist" and args.regressor != "ridge":
        raise UsageError("--regressor goes with --model gist")
    if fam.trainer != "multinet" and (args.modes or args.mtl or args.trials != 1):
        raise UsageError("--modes, --mtl and --trials go with --model z2color")
    if args.history and not fam.temporal:
        raise UsageError(f"--history goes with a model that reads earlier frames (mobilenet), not {args.model}")
    if args.init is not None:   # opened now: a damaged or foreign checkpoint is refused before any work
        from perception.shards import Dataset  # lazy: pyarrow
        if not Path(args.init).is_file():
            raise UsageError(f"--init: no such file: {args.init}")
        check_checkpoint(args.init, Dataset(first_root(args.data)).world)
    if args.modes is not None and not [m for m in args.modes.split(",") if m.strip()]:
        raise UsageError(f"--modes {args.modes!r} names no mode (leave it out for all the dataset has)")
    if args.weights:
        if not Path(args.weights).is_file():
            raise UsageError(f"--weights: no such file: {args.weights}")
    if args.emphasis != 1:
        check_emphasis(first_root(args.data))

    if args.batch_size is not None:   # a batch whose inputs cannot fit is refused before anything is allocated
        check_batch_for(args)

    from perception.train import train  # lazy: torch, pyarrow
    from perception.training import config_from  # lazy: torch, pyarrow

    train(config_from(**vars(args)))
    return 0
