"""`drivestudio train`: the trainer a model family names ("sgd": perception/train_sgd.py, "closed-form": GIST's
fit in perception/gist_fit.py, "multinet": Z2Color's in perception/multinet.py), for any world whose declaration
the family fits. What the trainers share is perception/training.py's."""
from __future__ import annotations

from perception.distributed import distributed_env, join_distributed
from perception.gist_fit import fit_gist
from perception.models import family
from perception.multinet import train_multinet
from perception.train_outputs import check_train_outputs
from perception.train_sgd import SGDRun
from perception.training import TrainConfig, TrainingError, open_data, resolve_device


def train(cfg: TrainConfig, log=print) -> dict:
    """Train (or continue training) `cfg.model` on `cfg.data`; returns the final checkpoint's `train` record."""
    trainer = family(cfg.model).trainer
    check_train_outputs(cfg.out, trainer)   # every file it writes, before the data is read
    if trainer != "sgd" and distributed_env() is not None:
        raise TrainingError(f"--model {cfg.model} trains in one process ({trainer}); torchrun runs the SGD families "
                            "(alexnet, vgg16, ...) on several")
    if trainer == "closed-form":
        return fit_gist(cfg, log)
    if trainer == "multinet":
        return train_multinet(cfg, log)
    data, decl, labels = open_data(cfg)
    dist, device = join_distributed(resolve_device(cfg.device))
    try:
        return SGDRun(cfg, data, decl, labels, device, dist, log if dist.main else (lambda *a, **k: None)).run()
    finally:
        dist.close()
