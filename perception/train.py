"""`drivestudio train`: one driver for every trainer (the protocol of perception/trainer.py). The trainer is the one
a model family names ("sgd": perception/train_sgd.py, "closed-form": GIST's fit in perception/gist_fit.py,
"multinet": Z2Color's in perception/multinet.py), for any world whose declaration the family fits. What the
trainers share is perception/training.py's."""
from __future__ import annotations

from core.allocator import keep_freed_memory
from core.settings import SettingError, entries
from core.signals import Terminated, exit_on_sigterm
from core.signals import check as check_signals
from perception.distributed import distributed_env, join_distributed
from perception.gist_fit import GistTrainer
from perception.models import Family, family
from perception.multinet import MultiNetTrainer
from perception.train_config import TrainConfig
from perception.train_outputs import check_train_outputs
from perception.train_sgd import SGDTrainer
from perception.trainer import Trainer
from perception.training import TrainingError, open_data, resolve_device

TRAINERS: dict[str, type[Trainer]] = {"sgd": SGDTrainer, "multinet": MultiNetTrainer, "closed-form": GistTrainer}
# the settings no trainer refuses: where the data, the model and the checkpoint are, the targets, the device, the seed
EVERY = frozenset({"data", "model", "out", "targets", "device", "seed"})


def train(cfg: TrainConfig, log=print) -> dict:
    """Train (or continue training) `cfg.model` on `cfg.data`; returns the final checkpoint's `train` record."""
    kind = family(cfg.model).trainer
    check_train_outputs(cfg.out, kind)   # every file it writes, before the data is read
    if kind != "sgd" and distributed_env() is not None:
        raise TrainingError(f"--model {cfg.model} trains in one process ({kind}); torchrun runs the SGD families "
                            "(alexnet, vgg16, ...) on several")
    if kind == "multinet":
        return run(MultiNetTrainer(cfg, log))
    if kind == "closed-form":
        return run(GistTrainer(cfg, log))
    data, decl, labels = open_data(cfg)
    dist, device = join_distributed(resolve_device(cfg.device))
    try:
        return run(SGDTrainer(cfg, data, decl, labels, device, dist, log if dist.main else (lambda *a, **k: None)))
    finally:
        dist.close()


def settings_read(fam: Family) -> frozenset[str]:
    """The settings of TrainConfig that a family's training reads: those of every trainer, its trainer's, and its
    own (VGG-16's unfreeze and batch_norm; a temporal family's history)."""
    return EVERY | TRAINERS[fam.trainer].reads | set(fam.settings) | ({"history"} if fam.temporal else set())


def check_reads(cfg: TrainConfig) -> None:
    """SettingError naming the settings given (other than their defaults) that the family's training does not
    read: it would ignore them."""
    fam = family(cfg.model)
    table = entries(TrainConfig)
    reads = settings_read(fam)
    given = [name for name, e in table.items() if name not in reads and getattr(cfg, name) != e.default]
    if given:
        takes = ", ".join(name for name in table if name in reads - EVERY)
        raise SettingError(f"{', '.join(given)} {'does' if len(given) == 1 else 'do'} not apply to --model "
                           f"{cfg.model} (its {fam.trainer} training reads {takes})")


def run(trainer: Trainer) -> dict:
    """Any trainer's run: its plan, its checkpoint continued, then its steps one after another. It validates every
    `validate_every` steps and at the last; it saves after each validation but the last (the end's save follows
    that one), between validations when the trainer's clock says so, and on Ctrl-C or SIGTERM. Returns the
    checkpoint's train record. A trainer whose steps repeat their allocations keeps freed memory from here on."""
    plan = trainer.plan()
    if plan.done is not None:   # the checkpoint has every step already: nothing is written
        return plan.done
    if trainer.repeats:
        keep_freed_memory()
    steps = trainer.restore()
    try:
        with exit_on_sigterm(poll=True):
            for n, work in steps:
                check_signals()
                due = trainer.step(work)
                if n % plan.validate_every == 0 or n == plan.steps:
                    trainer.validate()
                    if n < plan.steps:
                        trainer.save("validation")
                elif due:
                    trainer.save("clock")
            return trainer.save("end")
    except (KeyboardInterrupt, Terminated):
        trainer.save("interrupt")
        raise
