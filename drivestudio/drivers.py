"""Drivers that need nothing of a world but its declaration: an end-to-end model whose outputs are the action."""
from __future__ import annotations

import time

import numpy as np

from core.declaration import WorldDeclaration, base_name
from drivestudio.errors import UsageError
from drivestudio.loop import Percept
from perception.history import History


class DirectDriver:
    """A model that predicts the action values themselves (its labels are named like the world's action). Over a
    horizon ("steer+1" .. "steer+10") the last step is actuated; `smooth` averages each command with the previous
    one, (x + previous) / 2, as MultiNet's cars do. The behavioural mode comes from the percept (the bridge's shared
    flag) or from `mode`."""

    def __init__(self, predictor, decl: WorldDeclaration, smooth: bool = False, mode: str | None = None):
        names = decl.action_names
        last = {}
        for i, out in enumerate(predictor.outputs):
            base = base_name(out)
            if base in names:
                last[base] = i   # outputs come step by step, so the last one seen is the farthest ahead
        missing = [n for n in names if n not in last]
        if missing:
            raise UsageError(f"{predictor.description} does not predict the {decl.name} world's action "
                             f"({', '.join(missing)} missing)")
        self.predictor, self.decl, self.smooth, self.mode = predictor, decl, smooth, mode
        self._pick = [last[n] for n in names]
        self._estimate_slot = [(i, decl.estimate_names.index(o)) for i, o in enumerate(predictor.outputs)
                               if o in decl.estimate_names]
        self.history = History(predictor.instants)
        self.previous: np.ndarray | None = None
        self.timings = {"perception": 0.0, "control": 0.0}
        self.name = predictor.name

    def reset(self) -> None:
        self.history.reset()
        self.previous = None

    def current_mode(self, percept: Percept) -> str | None:
        if self.mode is not None or not self.predictor.modes:
            return self.mode
        index = getattr(percept, "behaviour", None)
        if index is None and self.decl.mode_field:
            index = int(percept.record[self.decl.index(self.decl.mode_field)])
        return None if index is None else self.decl.modes[int(index)]

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        images = self.history.push(percept.frames)
        values = self.predictor(images, self.current_mode(percept))
        t1 = time.perf_counter()
        command = values[self._pick]
        if self.smooth and self.previous is not None:
            command = (command + self.previous) / 2
        command = self.decl.clip_action(command)
        self.previous = command
        estimate = np.full(len(self.decl.estimate_names), np.nan)
        for i, j in self._estimate_slot:
            estimate[j] = values[i]
        self.timings["perception"] += t1 - t0
        self.timings["control"] += time.perf_counter() - t1
        return command, estimate
