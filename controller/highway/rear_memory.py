"""Rear memory: a car seen closing in the mirror is remembered alongside once the mirror loses it.

The rear-view mirror (the frame's inset) shows a car in a neighbour lane until it is a few metres behind the host's
bumper; closer than that it is in the blind spot, in neither view, and then ahead in the front camera once it has
passed. A network that reads the rear gap (`dist_LB` / `dist_RB`) then reads "far" exactly when the car is
alongside, and the lookout's rule L1 lets the host change lanes into it (the extended set's crash clips on the
random suite: a car alongside read at 26.8 m, one 3.4 m behind read at 16 m and a second later at 70 m). It is the
pass memory's counterpart behind (controller/highway/pass_memory.py carries a car the host passes; this one a car
that passes the host).

The rule: a car read nearer than `near` for at least `min_seen` frames in a row with a mean estimated closing
speed above `min_closing`, and then lost (read at `near` or beyond), is taken to be in the blind spot: the gap
reads 0 (alongside) and the closing speed its mean while seen, for as long as such a car takes to pass the host by
`ahead` metres at that speed (both cars' lengths and a margin), at most `max_s`. Alongside rather than dead-reckoned
from the last reading: the mirror loses a car only in the blind spot, and the networks read the nearest cars in
the mirror as farther than they are (so a gap carried on from the last reading would free the lane too early).
While carried, a near reading does not end it (a car alongside is misread as near-behind too); the smaller gap and
the larger closing speed are what the lookout reads. A lane change forgets it (the lanes change meaning).

A driver with the rear memory also hands the cars it passes over to the mirror (controller/highway/pass_memory.py,
`behind_seen`): the same blind spot hides a passed car that speeds up.
"""
from __future__ import annotations

from collections import deque

import numpy as np

FRAME_S = 0.1            # the controller's frame (10 Hz)


class RearMemory:
    """One neighbour lane's rear gap and closing speed: `filter(gap, closing)` once a frame returns what the
    lookout should read."""

    def __init__(self, max_s: float = 10.0, near: float = 25.0, min_seen: int = 3, window: int = 10,
                 min_closing: float = 0.3, ahead: float = 15.0):
        self.max_s = max_s                # [s] longest a car is held alongside
        self.near = near                  # [m] a reading below this is a car behind worth remembering
        self.min_seen = min_seen          # near readings in a row before a car counts as seen
        self.min_closing = min_closing    # [m/s] a slower car never reaches the blind spot: not carried
        self.ahead = ahead                # [m] how far the car moves past the host before the lane is free
        self.seen: deque[tuple[int, float]] = deque(maxlen=window)   # (frame, closing) of the last near readings
        self.carried: tuple[int, int, float] | None = None            # (frame lost, frames held, closing speed)
        self.frame = 0

    def reset(self) -> None:
        self.seen.clear()
        self.carried = None

    def _hold(self, closing: float) -> int:
        """Frames a car passing at `closing` [m/s] is held alongside."""
        return round(min(self.max_s, self.ahead / closing) / FRAME_S)

    def filter(self, gap: float, closing: float) -> tuple[float, float]:
        """The rear gap [m] and closing speed [m/s] the lookout should read this frame, from the estimates."""
        self.frame += 1
        if self.carried is not None and self.frame - self.carried[0] >= self.carried[1]:
            self.carried = None                   # passed: the front camera has it now
        if gap < self.near:
            if self.seen and self.seen[-1][0] != self.frame - 1:
                self.seen.clear()                 # not the same stretch of readings
            self.seen.append((self.frame, closing))
        else:
            if self.carried is None and len(self.seen) >= self.min_seen and self.seen[-1][0] == self.frame - 1:
                rate = float(np.mean([c for _, c in self.seen]))
                if rate > self.min_closing:
                    self.carried = (self.frame, self._hold(rate), rate)
            self.seen.clear()
        if self.carried is not None:
            return 0.0, max(closing, self.carried[2])   # alongside: the lane is taken
        return gap, closing
