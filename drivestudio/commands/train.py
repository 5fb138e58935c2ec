"""drivestudio train --data DIR --model NAME --out CKPT: fit a perception model of the dataset's world."""
from __future__ import annotations

from drivestudio.checkpoints import check_device
from drivestudio.commands.common import add_device_option
from drivestudio.errors import UsageError
from drivestudio.numbers import count, finite, positive, seed

FAMILIES = "alexnet (AlexNet), vgg16 (VGG-16), gist (GIST + ridge), z2color (Z2Color: MultiNet and its MTL baseline)"


def register(sub) -> None:
    lines = FAMILIES   # the registry imports torch: the parser must not (every verb would start seconds slower)
    p = sub.add_parser("train", help="train a model (AlexNet, VGG-16, GIST, Z2Color, ...) on a dataset",
                       description="Train a model of the dataset's world. Models: " + lines + ". The highway's "
                                   "defaults are Liu and Wang's: SGD momentum 0.9, lr x0.9 every 1000 iterations, "
                                   "AlexNet lr 1e-2 batch 15 for 10,000 iterations, VGG-16 (conv frozen) lr 1e-4 "
                                   "batch 10 for 15,000; Euclidean loss on targets normalised to [0.1, 0.9]. GIST is "
                                   "fitted in closed form. Running the same command again continues from the "
                                   "checkpoint; loss curves are written beside it as CKPT.loss.csv and .png.")
    p.add_argument("--data", required=True, help="dataset folder written by `drivestudio generate`")
    p.add_argument("--model", required=True, help="the model family: one that fits the dataset's world")
    p.add_argument("--out", required=True, help="checkpoint file to write (and to continue from if it exists)")
    p.add_argument("--targets", help="comma-separated labels to learn (default: the world's); +NAME adds to the "
                                     "default, e.g. +fast,+lanes_left")
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
    p.add_argument("--weight-decay", type=finite(0.0, 1.0), default=0.0,
                   help="L2 weight decay (default 0)")
    add_device_option(p, "auto")
    p.add_argument("--no-amp", dest="amp", action="store_false", help="no mixed precision on CUDA")
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
    p.add_argument("--init", metavar="CKPT", help="z2color: start from this checkpoint's weights (fine-tuning, as the "
                                                  "correction rounds of `study` and `autonomy --rounds` do)")
    p.add_argument("--seed", type=seed(), default=0, help="seed of initialisation and data order")
    p.set_defaults(func=run)


def run(args) -> int:
    from core.files import check_output
    from perception.models import family

    check_device(args.device)
    check_output(args.out, (".pt", ".pth", ".ckpt"), "checkpoint")   # before any work, not after the fit
    fam = family(args.model)
    if args.model != "vgg16" and (args.unfreeze or args.batch_norm):
        raise UsageError("--unfreeze and --batch-norm go with --model vgg16")
    if args.model == "gist" and args.weights:
        raise UsageError("--weights goes with --model vgg16 or alexnet")
    if args.model != "gist" and args.regressor != "ridge":
        raise UsageError("--regressor goes with --model gist")
    if fam.trainer != "multinet" and (args.modes or args.mtl or args.trials != 1 or args.init):
        raise UsageError("--modes, --mtl, --trials and --init go with --model z2color")
    from pathlib import Path
    for option, path in (("--weights", args.weights), ("--init", args.init)):
        if path and not Path(path).is_file():
            raise UsageError(f"{option}: no such file: {path}")

    from perception.train import config_from, train

    train(config_from(**vars(args)))
    return 0
