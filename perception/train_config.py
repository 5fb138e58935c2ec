"""The configuration of a training (perception/train.py): every setting once, with its default, unit and limits
(core/settings.py). `drivestudio train` derives its command line from it (drivestudio/commands/train.py): the
settings most runs give are flags, every other one is `--set NAME=VALUE`. A family's trainer reads some of the
settings (its `reads`, perception/trainer.py) and the command refuses the others, which it would ignore. Apart from
perception/training.py so that the command line's --help imports no torch.

The defaults are Liu and Wang's (Deeper Direct Perception, sections 6.1 and 6.3): SGD with momentum 0.9, learning
rate x0.9 every 1000 iterations; the settings whose default is a family's (iterations, batch, learning rate,
optimiser, loss, moving average: None here) take it from the family's `defaults` (perception/models.py).
"""
from __future__ import annotations

from dataclasses import dataclass

from core.settings import MAX_SEED, setting

LOSS_NAMES = ("euclidean", "l1")   # perception/training.py's LOSSES, by name (tests/perception/test_training.py)


@dataclass
class TrainConfig:
    # the run's data, model and checkpoint
    data: str = setting("out/dataset", "dataset folder written by `drivestudio generate` (z2color: several, "
                                       "comma-separated)")
    model: str = setting("alexnet", "the model family: one that fits the dataset's world")
    out: str = setting("runs/alexnet.pt", "checkpoint file to write, and to continue from if it exists")
    targets: str | None = setting(None, "the labels to learn: a label set of the world by name (highway: paper, the "
                                        "default, or extended: docs/affordances.md), NAME,NAME in place of the "
                                        "default, or +NAME,+NAME added to it (e.g. +fast,+lanes_left, or "
                                        "extended,+NAME)")
    # a library caller's shorthands for targets (not settings: the command line has --targets alone)
    labels: str | None = None          # a named label set of the world as the default targets
    # how long and how fast
    iterations: int | None = setting(None, "training iterations (none: the model family's)", low=1, high=10**8)
    epochs: float | None = setting(None, "passes over the training split, in place of iterations", low=0.001,
                                   high=10**5)
    batch_size: int | None = setting(None, "samples per iteration (none: the model family's)", low=1, high=65536)
    lr: float | None = setting(None, "initial learning rate (none: the model family's)", low=1e-9, high=100.0)
    lr_step: int = setting(1000, "iterations between learning-rate decays", low=1, high=10**8)
    lr_gamma: float = setting(0.9, "learning-rate decay factor", low=1e-6, high=1.0)
    optimizer: str | None = setting(None, "sgd (Liu and Wang's, with momentum), adam or adadelta (MultiNet's); none: "
                                          "the model family's", choices=("sgd", "adam", "adadelta"))
    loss: str | None = setting(None, "euclidean (the papers': half the squared error) or l1 (the absolute error the "
                                     "MAE reports measure, every output pulling alike); none: the checkpoint's "
                                     "when continuing or starting from one (init), else the model family's (l1 "
                                     "for mobilenet)", choices=LOSS_NAMES)
    ema: float | None = setting(None, "decay per step of the moving average of the weights, which is validated and "
                                      "saved (0.995: about the last 200 steps; 0: none; none: the model family's, "
                                      "0.995 for mobilenet)", low=0.0, high=0.9999)
    momentum: float = setting(0.9, "SGD's momentum", low=0.0, high=0.9999)
    weight_decay: float = setting(0.0, "L2 weight decay", low=0.0, high=1.0)
    device: str = setting("auto", "torch device: auto, cpu, cuda or cuda:N")
    amp: bool = setting(True, "mixed precision: on CUDA (bfloat16 where supported, else float16) and bfloat16 "
                              "autocast on a CPU that computes bfloat16 natively (AVX512-BF16 or AMX); false: "
                              "float32 throughout")
    workers: int = setting(1, "processes decoding frames", low=0, high=64)
    shuffle_buffer: int = setting(16384, "frames mixed across episodes before batching", low=1, high=10**7)
    val_every: int = setting(500, "iterations between validations (and checkpoints)", low=1, high=10**8)
    checkpoint_every: float = setting(300.0, "also save at least this often (a kill loses at most this much)",
                                      unit="s", low=0.001, high=10**6)
    val_frames: int = setting(1000, "validation frames at most, evenly spread over the split", low=1, high=10**7)
    log_every: int = setting(10, "iterations per row of the loss curve", low=1, high=10**8)
    unfreeze: bool = setting(False, "vgg16: train the convolutional layers too")
    batch_norm: bool = setting(False, "vgg16: VGG-16 with batch normalisation")
    weights: str | None = setting(None, "torchvision ImageNet state dict for the convolutional trunk (e.g. "
                                        "vgg16-397923af.pth, alexnet-owt-7be5be79.pth) that you already have; "
                                        "nothing is downloaded")
    fast: bool = False                 # highway: predict `fast` too (= targets "+fast")
    lanes_left: bool = False           # highway: predict lanes_left too (= targets "+lanes_left")
    regressor: str = setting("ridge", "gist: linear ridge or RBF kernel ridge (random Fourier features)",
                             choices=("ridge", "rbf"))
    modes: str | None = setting(None, "z2color: the behavioural modes to train on, comma-separated (none: all the "
                                      "dataset has)")
    mtl: str | None = setting(None, "z2color: the MTL baseline, without the modal input, trained on this one mode's "
                                    "data")
    trials: int = setting(1, "z2color: trainings with fresh seeds, for curves with confidence intervals", low=1,
                          high=100)
    mode_moments: int | None = setting(None, "z2color: an epoch draws at most this many moments of each behavioural "
                                             "mode, afresh each epoch (none: one pass over the training split)",
                                       low=1, high=10**9)
    steer_share: float = setting(0.0, "z2color: the share of each mode's draws from its steering moments (the "
                                      "actuated steering at least 0.1 from straight ahead; the MultiNet authors' "
                                      "code draws half and half; docs/sidewalk.md)", low=0.0, high=1.0)
    init: str | None = setting(None, "start from this checkpoint's weights (the same family, world and targets): "
                                     "fine-tuning, aggregation rounds, the correction rounds of study and autonomy")
    history: int = setting(0, "mobilenet: earlier frames read beside the current one, 0.1 s apart", low=0, high=2)
    cache: bool = setting(True, "decode the training frames once into the dataset's frame cache (DATA/.frames)")
    channels_last: bool = setting(True, "CPU: channels-last weights and inputs (oneDNN's faster convolutions)")
    emphasis: int = setting(1, "an epoch shows the world's decisive steps this many times, every other step once "
                               "(highway: a car closer than 20 m ahead in the host's or a neighbouring lane; "
                               "docs/aggregation.md)", low=1, high=100)
    seed: int = setting(0, "seed of initialisation and data order", low=0, high=MAX_SEED)
