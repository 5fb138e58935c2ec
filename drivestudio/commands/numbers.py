"""Numbers read from the command line: argparse `type=` functions that refuse NaN, infinities, negatives and
absurd sizes with one clear line (argparse prefixes "argument --X: " and exits with status 2)."""
from __future__ import annotations

import argparse
import math
from typing import overload

MAX_SEED = 2**32 - 1


@overload
def _number(text: str, kind: type[int]) -> int: ...


@overload
def _number(text: str, kind: type[float]) -> float: ...


def _number(text: str, kind: type[int] | type[float]) -> int | float:
    try:
        value = kind(text)
    except (TypeError, ValueError):
        what = "an integer" if kind is int else "a number"
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}") from None
    if kind is float and not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def count(low: int = 0, high: int = 10**9):
    """An integer from low to high."""
    def parse(text: str) -> int:
        v = _number(text, int)
        if not low <= v <= high:
            raise argparse.ArgumentTypeError(f"must be an integer from {low} to {high}, got {v}")
        return v
    parse.__name__ = "integer"
    return parse


def finite(low: float = -math.inf, high: float = math.inf, low_open: bool = False):
    """A finite number in [low, high] ((low, high] with low_open)."""
    def parse(text: str) -> float:
        v = _number(text, float)
        if v < low or v > high or (low_open and v == low):
            lo = "(" if low_open else "["
            raise argparse.ArgumentTypeError(f"must be in {lo}{low:g}, {high:g}], got {text}")
        return v
    parse.__name__ = "number"
    return parse


def positive(high: float = math.inf):
    """A finite number > 0 and <= high."""
    return finite(0.0, high, low_open=True)


def non_negative(high: float = math.inf):
    return finite(0.0, high)


def seed():
    """A seed: an integer from 0 to 2**32 - 1."""
    return count(0, MAX_SEED)
