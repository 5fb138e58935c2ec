"""drivestudio train --data DIR --model alexnet|vgg16|gist --out CKPT: fit a perception model (seed 002 §6)."""
from __future__ import annotations

from ..errors import UsageError


def register(sub) -> None:
    p = sub.add_parser("train", help="train AlexNet, VGG-16 or the GIST baseline on a dataset",
                       description="Train a model that maps a 280x210 frame to the 13 DeepDriving indicators "
                                   "(14 with --fast, +lanes_left with --lanes-left). Defaults are seed 002's: SGD "
                                   "momentum 0.9, lr x0.9 every 1000 iterations, AlexNet lr 1e-2 batch 15 for 10,000 "
                                   "iterations, VGG-16 (conv frozen) lr 1e-4 batch 10 for 15,000; Euclidean loss on "
                                   "targets normalised to [0.1, 0.9]. GIST is fitted in closed form. Running the same "
                                   "command again continues from the checkpoint; loss curves are written beside it "
                                   "as CKPT.loss.csv and CKPT.loss.png.")
    p.add_argument("--data", required=True, help="dataset folder written by `drivestudio generate`")
    p.add_argument("--model", required=True, choices=("alexnet", "vgg16", "gist"))
    p.add_argument("--out", required=True, help="checkpoint file to write (and to continue from if it exists)")
    length = p.add_mutually_exclusive_group()
    length.add_argument("--iterations", type=int, help="training iterations (default 10000 alexnet, 15000 vgg16)")
    length.add_argument("--epochs", type=float, help="passes over the training split, instead of --iterations")
    p.add_argument("--batch-size", type=int, help="frames per iteration (default 15 alexnet, 10 vgg16)")
    p.add_argument("--lr", type=float, help="initial learning rate (default 1e-2 alexnet, 1e-4 vgg16)")
    p.add_argument("--lr-step", type=int, default=1000, help="iterations between learning-rate decays (1000)")
    p.add_argument("--lr-gamma", type=float, default=0.9, help="learning-rate decay factor (0.9)")
    p.add_argument("--optimizer", choices=("sgd", "adam"), default="sgd", help="sgd with momentum 0.9 (default) "
                   "or adam")
    p.add_argument("--weight-decay", type=float, default=0.0, help="L2 weight decay (default 0)")
    p.add_argument("--device", default="auto", help="auto (cuda if available), cpu, cuda or cuda:N")
    p.add_argument("--no-amp", dest="amp", action="store_false", help="no mixed precision on CUDA")
    p.add_argument("--workers", type=int, default=1, help="processes decoding frames (default 1)")
    p.add_argument("--val-every", type=int, default=500, help="iterations between validations and checkpoints")
    p.add_argument("--val-frames", type=int, default=1000, help="validation frames used (default 1000)")
    p.add_argument("--unfreeze", action="store_true", help="vgg16: train the convolutional layers too")
    p.add_argument("--batch-norm", action="store_true", help="vgg16: use VGG-16 with batch normalisation")
    p.add_argument("--weights", help="torchvision ImageNet state dict for the convolutional trunk (e.g. "
                   "vgg16-397923af.pth, alexnet-owt-7be5be79.pth) that you already have; nothing is downloaded")
    p.add_argument("--fast", action="store_true", help="also predict the 14th indicator, fast")
    p.add_argument("--lanes-left", action="store_true", help="also predict lanes_left (seed 002 §6.5's fix)")
    p.add_argument("--regressor", choices=("ridge", "rbf"), default="ridge",
                   help="gist: linear ridge (default) or RBF kernel ridge (random Fourier features)")
    p.add_argument("--seed", type=int, default=0, help="seed of initialisation and data order")
    p.set_defaults(func=run)


def run(args) -> int:
    for name in ("iterations", "batch_size", "lr_step", "val_every", "val_frames"):
        value = getattr(args, name)
        if value is not None and value < 1:
            raise UsageError(f"--{name.replace('_', '-')} must be at least 1")
    if args.epochs is not None and args.epochs <= 0:
        raise UsageError("--epochs must be positive")
    if args.lr is not None and args.lr <= 0:
        raise UsageError("--lr must be positive")
    if args.workers < 0:
        raise UsageError("--workers must not be negative")
    if args.model != "vgg16" and (args.unfreeze or args.batch_norm):
        raise UsageError("--unfreeze and --batch-norm go with --model vgg16")
    if args.model == "gist" and args.weights:
        raise UsageError("--weights goes with --model vgg16 or alexnet")
    if args.model != "gist" and args.regressor != "ridge":
        raise UsageError("--regressor goes with --model gist")

    from perception.train import config_from, train

    train(config_from(**vars(args)))
    return 0
