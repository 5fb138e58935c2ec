"""The trainer protocol: what every model family's trainer fills in, so that one driver (perception/train.py) runs
them all: the SGD trainer of the regressors (perception/train_sgd.py), Z2Color's (perception/multinet.py) and the
GIST baseline's closed-form fit (perception/gist_fit.py).

A trainer's run is a number of steps, whatever a step is for it (an iteration of SGD, an epoch of one MultiNet
trial, the one closed-form fit): `plan` says how many and how often to validate, `restore` continues the checkpoint
at `out` and hands over the steps still to do, `step` takes one, `validate` measures the model as it is, `save`
writes the checkpoint and its loss curves for one of the occasions the driver has.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, ClassVar, Literal, Protocol

# why the driver saves: after a validation, by the trainer's clock between validations, at the end, on Ctrl-C or
# SIGTERM (a trainer whose checkpoint holds only whole steps writes nothing then: it has saved the last one)
Occasion = Literal["validation", "clock", "end", "interrupt"]


@dataclass(frozen=True)
class Plan:
    """What a run does, as its trainer resolved it from the configuration, the family and the checkpoint."""

    steps: int = 0               # the run's steps in all, those its checkpoint has done included
    validate_every: int = 1      # steps between validations (and at the last step)
    done: dict | None = None     # the train record of a checkpoint that has every step already: nothing to do


class Trainer(Protocol):
    # the settings of TrainConfig (perception/train_config.py) it reads besides those every trainer reads: the
    # command refuses any other one given, since the trainer would ignore it
    reads: ClassVar[frozenset[str]]
    # whether its steps allocate blocks of the same sizes over and over (SGD iterations, MultiNet's epochs): then the
    # run keeps freed memory for the next step (core/allocator.py). Not for a pass that keeps results as it goes
    # (GIST's descriptors): kept results split the freed blocks, and the heap grows by a block a batch
    repeats: ClassVar[bool]

    def plan(self) -> Plan:
        """The run's steps and validations; a checkpoint at `out` is checked against the settings first."""
        ...

    def restore(self) -> Iterator[tuple[int, Any]]:
        """Continue the checkpoint at `out` (if there is one); the steps still to do, each as (the steps done once
        it is, what the step works on)."""
        ...

    def step(self, work: Any) -> bool:
        """Take one step; whether a save is due by the trainer's clock."""
        ...

    def validate(self) -> None:
        """Measure the model as it is now on the validation data, into the loss curve."""
        ...

    def save(self, occasion: Occasion) -> dict:
        """Write the checkpoint and the loss curves beside it as `occasion` asks; the checkpoint's train record."""
        ...
