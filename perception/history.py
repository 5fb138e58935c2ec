"""The frames of the last steps, for a driver that sees one step at a time but whose model reads several instants
(MultiNet's data moment; a highway model with earlier frames). Plain Python: drivers import it without torch."""
from __future__ import annotations


class History:
    """The images of the last steps, so that a driver seeing one step at a time can build samples that reach back
    (MultiNet's moment: the stereo pair now and one step earlier). Before enough steps have been seen, the
    earliest available step stands in for the missing ones."""

    def __init__(self, instants: tuple[int, ...] = (0,)):
        self.instants = tuple(instants)
        self.depth = -min(self.instants) + 1
        self._steps: list[tuple] = []

    def reset(self) -> None:
        self._steps.clear()

    def push(self, frames) -> list:
        """Add this step's images (one per camera) and return the sample's images, oldest instant first."""
        self._steps.append(tuple(frames))
        if len(self._steps) > self.depth:
            self._steps.pop(0)
        out: list = []
        for dt in self.instants:
            k = max(0, len(self._steps) - 1 + dt)
            out.extend(self._steps[k])
        return out
