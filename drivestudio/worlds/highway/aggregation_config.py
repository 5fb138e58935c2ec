"""The settings of a data-aggregation run (drivestudio/worlds/highway/aggregation.py, docs/aggregation.md), each
with its default and limits once: `drivestudio aggregate` derives its command line from them and the run writes them
to its folder's config.json. Apart from the rounds' code so that --help imports neither torch nor SUMO."""
from __future__ import annotations

from dataclasses import dataclass

from core.settings import MAX_SEED, SettingError, setting
from sim.highway.config import MAX_CARS


def car_range(text: str) -> tuple[int, int]:
    """AI cars per episode as `N` or `A-B` (drawn per episode), from 0 to MAX_CARS."""
    lo, _, hi = str(text).partition("-")
    try:
        a, b = int(lo), int(hi or lo)
    except ValueError:
        raise SettingError(f"cars: expected N or A-B, got {text!r}") from None
    if not 0 <= a <= b <= MAX_CARS:
        raise SettingError(f"cars must be from 0 to {MAX_CARS} (and A <= B), got {text!r}")
    return a, b


def cars_text(text: str) -> str:
    """The cars setting as given, once it reads as a range."""
    car_range(text)
    return str(text).strip()


@dataclass(frozen=True)
class AggregationConfig:
    # the run's inputs and folder: no defaults (given as flags, or by a --config file)
    data: str = setting(None, "the expert dataset the model was trained on")
    model: str = setting(None, "the model of round 0 (a highway checkpoint)")
    out: str = setting(None, "the run's folder (rounds, merged datasets, models, benchmark)")
    # the rounds
    rounds: int = setting(3, "aggregation rounds", low=1, high=50)
    frames: int = setting(4000, "visited frames recorded per round", low=20, high=10**7)
    beta: float = setting(0.5, "the expert's share of the steps in round 1", low=0.0, high=1.0)
    decay: float = setting(0.5, "the expert's share shrinks by this factor per round", low=0.0, high=1.0)
    episode_frames: int = setting(200, "steps per episode", low=20, high=10**6)
    cars: str = setting("12-40", "AI cars per episode, N or A-B", parse=cars_text)
    # the fine-tuning after each round
    iterations: int = setting(2000, "fine-tuning iterations per round", low=1, high=10**7)
    batch_size: int | None = setting(None, "fine-tuning batch (none: the model family's)", low=1, high=4096)
    lr: float | None = setting(None, "fine-tuning learning rate (none: the model family's)", low=1e-9, high=10.0)
    emphasis: int = setting(1, "the fine-tuning shows the decisive frames (a car closer than 20 m ahead in the host's "
                               "or a neighbouring lane) this many times an epoch (1: as recorded; train's emphasis)",
                            low=1, high=100)
    # the benchmark at the end, and how the run is spread
    suite: str = setting("default", "the benchmark suite every round's model drives at the end: a shipped "
                                    "suite's name (default, random, ...) or a suite file; 'none': none")
    seed: int = setting(0, "seed of the rounds' traffic and mixing", low=0, high=MAX_SEED)
    workers: int | None = setting(None, "worker processes driving episodes and routes (none: one per core)",
                                  low=1, high=256)
    device: str = setting("cpu", "torch device: cpu, cuda, cuda:N or auto")

    def beta_of(self, round_: int) -> float:
        return self.beta * self.decay ** (round_ - 1)

    @property
    def car_range(self) -> tuple[int, int]:
        return car_range(self.cars)
