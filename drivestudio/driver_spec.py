"""What drives, as one string every verb reads alike: `NAME_OR_CKPT[@filter=value,...]`.

    oracle                                     a world's own driver
    runs/alexnet.pt                            a checkpoint
    runs/alexnet.pt@smoothing=0.5              ... with an estimate filter
    runs/ex.pt@pass_memory=15,rear_memory=10   ... with several, applied in the world's order

The world declares its estimate filters (name, range, unit; the highway: drivestudio/worlds/highway/filters.py);
`parse_driver` is the one parser of the syntax, and `DriverSpec` the parsed value a world's Plugin turns into a
driver. A filter set to 0 is no filter, so `CKPT@smoothing=0` and `CKPT` are the same driver.
"""
from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from drivestudio.errors import UsageError

_PAIR = re.compile(r"([a-z_]+)=(.*)")


@dataclass(frozen=True)
class EstimateFilter:
    """One filter a world's drivers apply to a model's estimates before its controller."""

    name: str
    high: float          # the largest value; the smallest is 0 (no filter)
    unit: str            # "" for a factor, "s" for a time
    help: str


@dataclass(frozen=True)
class DriverSpec:
    """A driver: its source (a world's own driver, a checkpoint or a policy) and its filters, in the world's order,
    each with a value above 0."""

    source: str
    filters: tuple[tuple[str, float], ...] = ()

    def get(self, name: str) -> float:
        """The value of filter `name` (0: not applied)."""
        return dict(self.filters).get(name, 0.0)

    def __str__(self) -> str:
        if not self.filters:
            return self.source
        return f"{self.source}@" + ",".join(f"{k}={_text(v)}" for k, v in self.filters)


def parse_driver(text: str, filters: Mapping[str, EstimateFilter] | None = None, exact: tuple[str, ...] = (),
                 option: str = "--model") -> DriverSpec:
    """The DriverSpec of `text`. With `filters` (a world's), filter names and ranges are checked and the filters
    put in that order; without, only the syntax (a driver attaching to a world it does not know yet). Drivers in
    `exact` read the exact labels and take no filter. A file whose name holds '@' is a file."""
    if not text.strip():
        raise UsageError(f"{option}: empty; give a driver name or a checkpoint file")
    source, given = text, {}
    head, at, tail = text.rpartition("@")
    if at and not Path(text).is_file():
        source = head
        if not source:
            raise UsageError(f"{option} {text}: no driver before '@'")
        for part in tail.split(","):
            m = _PAIR.fullmatch(part.strip())
            if m is None:
                raise UsageError(f"{option} {text}: after '@' come filters as name=value, got {part!r}")
            if m[1] in given:
                raise UsageError(f"{option} {text}: {m[1]} is given twice")
            given[m[1]] = _value(m[1], m[2], filters, text, option)
    given = {k: v for k, v in given.items() if v}
    if source in exact and given:
        raise UsageError(f"{option} {text}: {source} reads the exact labels; {', '.join(given)} applies to "
                         "checkpoints")
    order = list(filters) if filters is not None else sorted(given)
    return DriverSpec(source, tuple((k, given[k]) for k in order if k in given))


def _text(v: float) -> str:
    """A value as it reads back exactly, without a trailing '.0'."""
    return str(int(v)) if v.is_integer() else repr(v)


def _value(name: str, value: str, filters: Mapping[str, EstimateFilter] | None, text: str, option: str) -> float:
    if filters is not None and name not in filters:
        known = ", ".join(f"{f.name}=" + ("S" if f.unit == "s" else "A") for f in filters.values())
        raise UsageError(f"{option} {text}: unknown filter {name!r}" +
                         (f" (this world's: {known})" if known else " (this world's drivers take none)"))
    try:
        v = float(value)
    except ValueError:
        v = math.nan
    high = filters[name].high if filters is not None else math.inf
    if not math.isfinite(v) or not 0.0 <= v <= high:
        unit = f" {filters[name].unit}" if filters is not None and filters[name].unit else ""
        raise UsageError(f"{option} {text}: {name} must be a number from 0 to {high:g}{unit}, got {value!r}")
    return v
