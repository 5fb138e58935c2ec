"""Errors that mean bad input: the CLI reports them in one line on stderr and exits with status 2."""
from __future__ import annotations


class UsageError(ValueError):
    """A bad combination of options, found after parsing."""


def input_errors() -> tuple[type[BaseException], ...]:
    from perception.shards import DatasetError
    from sim.errors import RendererError, TrafficError
    from sim.scenario import ScenarioError
    from sim.track import TrackError
    return (UsageError, TrackError, ScenarioError, RendererError, TrafficError, DatasetError)
