"""The models a benchmark compares: `oracle` (the Chen controller on the exact indicators, the upper bound),
`oracle-extended` (the lookout controller, controller/highway/lookout.py, on the exact extended labels: it also
sees the cars beside and behind) or a checkpoint of the highway world, optionally with the controller-side filters
of its estimates in the driver spec's syntax (drivestudio/driver_spec.py), or a trained policy on the exact
affordances (drivestudio/worlds/highway/policy.py).

    --model oracle
    --model oracle-extended
    --model runs/alexnet.pt
    --model runs/alexnet.pt@smoothing=0.5      e = 0.5 e_previous + 0.5 e_now before the Chen controller
    --model runs/alexnet.pt@gap_hold=0.8       gaps: g = min(g_now, 0.8 g_held + 0.2 g_now)
    --model runs/alexnet.pt@smoothing=0.3,gap_hold=0.8
    --model runs/alexnet.pt@pass_memory=10     a car being passed is carried on unseen for up to 10 s
    --model runs/ex.pt@rear_memory=10          a car lost from the mirror is held alongside for up to 10 s
    --model runs/ppo-highway.zip               a saved Stable-Baselines3 policy (drivestudio/worlds/highway/rl_train.py)
    --model policy:mypackage.drivers:careful   any callable from the affordance observation to an action

Every checkpoint is opened and checked before anything is driven: a missing file, a file that is no checkpoint,
or a model of another world (a sidewalk Z2Color) is refused in one line (exit status 2).
"""
from __future__ import annotations

import re
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from drivestudio.checkpoints import check_checkpoint_path
from drivestudio.driver_spec import DriverSpec, parse_driver
from drivestudio.errors import UsageError
from drivestudio.worlds.highway.filters import FILTERS, make_filters
from drivestudio.worlds.highway.policy import CALLABLE, is_policy

ORACLE = "oracle"
EXTENDED = "oracle-extended"
EXACT = (ORACLE, EXTENDED)   # the drivers on exact labels; the plain oracle's row is the upper bound


@dataclass(frozen=True)
class ModelSpec:
    """A row of the benchmark: its driver spec and what the checkpoint behind it is."""

    text: str                  # as given on the command line
    path: str | None           # the checkpoint; None: an oracle (exact labels)
    label: str = ORACLE        # the row's name in the leaderboard
    family: str = ORACLE       # "oracle", "oracle-extended", "alexnet", "gist", "vgg16", ...
    outputs: tuple = ()
    lookout: bool = False      # the lookout controller (rules L1-L3, docs/controller.md) instead of Chen's
    policy: bool = False       # a policy on the exact affordances (path: its .zip or policy:MODULE:NAME)
    inset: str = ""            # what the checkpoint's frames held besides the scene (the mirror): its routes render it
    filters: tuple = ()        # the driver spec's estimate filters, (name, value) in FILTERS' order

    @property
    def driver(self) -> DriverSpec:
        return DriverSpec(self.path or self.family, tuple(self.filters))

    @property
    def key(self) -> str:
        """What identifies the row: the same checkpoint with other filters is another row."""
        if self.policy and self.path is not None:
            return self.path if self.path.startswith(CALLABLE) else f"policy:{Path(self.path).resolve()}"
        return self.family if self.path is None else str(replace(self.driver, source=str(Path(self.path).resolve())))

    @property
    def is_oracle(self) -> bool:
        """The plain oracle: the paper's controller on the exact indicators, the row every other is compared with."""
        return self.path is None and self.family == ORACLE

    @property
    def exact(self) -> bool:
        """Drives on exact labels (either oracle): no perception, so no estimate to compare with the truth."""
        return self.path is None

    def as_dict(self) -> dict:
        d = asdict(self)
        d["outputs"], d["filters"] = list(self.outputs), [list(f) for f in self.filters]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> ModelSpec:
        return cls(**{**d, "outputs": tuple(d.get("outputs", ())),
                      "filters": tuple(tuple(f) for f in d.get("filters", ()))})


def check_model(text: str) -> ModelSpec:
    """The model of a --model value, its checkpoint opened and checked (a model of the highway world)."""
    if is_policy(text):   # opened now, as a checkpoint is: one line and exit 2 when it cannot drive
        from drivestudio.worlds.highway.policy import (
            PolicyDriver,  # lazy: Stable-Baselines3 and torch, only for a policy row
        )
        return ModelSpec(text, text, label=PolicyDriver(text).name, family="policy", policy=True)
    spec = parse_driver(text, FILTERS, EXACT)
    path = spec.source
    if path in EXACT:
        return ModelSpec(text, None, label=path, family=path, lookout=path == EXTENDED)
    from drivestudio.worlds.highway.drivers import reads_behind  # lazy: the controllers, only for a checkpoint
    from perception.checkpoint import load_checkpoint  # lazy: torch
    from perception.models import check_spec, describe, frame_inset  # lazy: torch
    check_checkpoint_path(path, EXACT)
    ckpt = load_checkpoint(path, world="highway")     # CheckpointError (exit 2): not ours, or another world's
    check_spec(ckpt["spec"], path)
    lookout = reads_behind(ckpt["spec"]["outputs"])
    make_filters(spec, lookout)   # a filter the model cannot take is refused now
    label = f"{describe(ckpt['spec'])} ({Path(path).name})" + \
        "".join(f", {f.replace('_', ' ')} {a:g}" for f, a in spec.filters) + (", lookout" if lookout else "")
    return ModelSpec(text, str(path), label=label, family=ckpt["spec"]["name"], outputs=tuple(ckpt["spec"]["outputs"]),
                     lookout=lookout, inset=frame_inset(ckpt["spec"]), filters=spec.filters)


def check_models(texts: list[str] | None) -> list[ModelSpec]:
    """The rows of a benchmark, the oracle first (added when not asked for: it is the upper bound every other row
    is compared with), then the extended oracle when asked for; a model given twice is refused."""
    models = [check_model(t) for t in (texts or [ORACLE])]
    seen: dict[str, str] = {}
    for m in models:
        if m.key in seen:
            raise UsageError(f"--model {m.text} is the same model as --model {seen[m.key]}; give each once")
        seen[m.key] = m.text
    oracle = [m for m in models if m.is_oracle] or [ModelSpec(ORACLE, None)]
    return distinct_labels(oracle + [m for m in models if m.exact and not m.is_oracle]
                           + [m for m in models if not m.exact])


def distinct_labels(models: list[ModelSpec]) -> list[ModelSpec]:
    """Rows whose labels coincide (checkpoints of one name in different folders, as the aggregation rounds'
    round-1/model.pt, round-2/model.pt, or two runs' runs/x/ensemble.pt) are named by as many of their path's last
    folders as tell them apart, so the leaderboard tells them apart."""
    labels = [m.label for m in models]
    out = []
    for m in models:
        if m.path is None or m.policy or labels.count(m.label) == 1:
            out.append(m)
            continue
        twins = [Path(t.path).resolve().parts for t in models if t.label == m.label and t.path is not None]
        own = Path(m.path).resolve().parts
        depth = next((k for k in range(2, len(own)) if sum(t[-k:] == own[-k:] for t in twins) == 1), len(own))
        name = "/".join(own[-depth:]).lstrip("/")
        out.append(replace(m, label=m.label.replace(f"({Path(m.path).name})", f"({name})")))
    return out


def slug(model: ModelSpec, taken: set[str]) -> str:
    """A file-name-safe short name of the model, unique among `taken` (clip folders)."""
    if model.exact:
        base = model.family
    else:
        base = re.sub(r"[^A-Za-z0-9_.+-]+", "-", Path(str(model.path)).stem).strip("-.") or "model"
        for f, a in model.filters:
            base += f"-{f.replace('_', '')}{a:g}"
    name, i = base, 2
    while name in taken:
        name, i = f"{base}-{i}", i + 1
    taken.add(name)
    return name
