"""Pass memory: a car being passed in a neighbour lane is remembered after the front camera loses it.

A car the host passes in the next lane leaves the 280x210 camera's view (75 degrees across) while it is still a few
metres ahead, so a network reads its gap (`dist_LL` / `dist_RR`) as "no car" from then on, whereas the true
indicator follows the car until it is level with the host. The Chen controller would then count the lane clear too
early, and its lane-preference rule would move the host into the car alongside. The filter carries the gap on through
the unseen stretch at the rate at which it was closing while seen (a straight-line fit of the last second of near
readings), and reads 0 once the car is level, until it is `clear_behind` behind the host or `max_s` passed; only
then does the controller's clear-lane timer start. Carrying the car only until level (where the true gap ends) is
not enough: the two-lane timer of 30 frames after an overtake would still let the host move back beside a car passed
slowly.

Two reckonings decide when the car is behind. Given the host's speed, the carried gap also closes by what the host
gained on the car since it was lost (the other car assumed to hold its speed): a host that slows down to follow the
car ahead while passing keeps a car alongside for longer than its closing rate when seen said. But the traffic a
host passes often speeds up with it (a platoon moving off together), so the host's speed must not shorten the
carry: the lane is given up only once the car is `clear_behind` at the rate it was seen closing too (the lane stays
taken as long as either reckoning says the car could still be beside the host). A car that the prediction puts back
beyond `near` ahead has pulled away into the camera's view and is no longer carried.

With the rear-view mirror, a passed car is handed over rather than reckoned away: the lane is given up only once
the rear view reads a car near behind in it too (the rear memory's driver passes `behind_seen`), since a car the
reckoning has behind but the mirror does not show may have sped up and still be alongside, in neither view.

The view also loses a car at its side in a way that looks like the car pulling away: a network reads a car that the
frame's edge cuts off as farther and farther. A car cannot open a gap faster than traffic moves apart, so with a
mirror a car read nearer than `beside` whose readings then open faster than `exit_rate` before it is lost is taken
to have left the view beside the host: the lane reads 0 until the mirror has the car near behind (or `max_s`
passed).

How each rule was found, from the crash clips that asked for it: docs/log.md.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from controller.highway.chen import ChenParams

FRAME_S = 0.1            # the controller's frame (10 Hz)


class PassMemory:
    """One neighbour lane's gap: `filter(g)` once a frame returns the gap the controller should read."""

    def __init__(self, near: float = ChenParams.occupied_gap, window: int = 10, min_seen: int = 3,
                 min_closing: float = 0.2, max_s: float = 10.0, clear_behind: float = 10.0, beside: float = 8.0,
                 exit_rate: float = 6.0):
        self.near = near                  # [m] a reading below this is a car (the controller's occupied gap)
        self.min_seen = min_seen          # near readings in a row before a car counts as seen
        self.min_closing = min_closing    # [m/s] slower closing: the car is not being passed
        self.max_s = max_s                # [s] longest a car is carried on unseen
        self.clear_behind = clear_behind  # [m] how far behind the host a passed car must be before its lane is free
        self.beside = beside              # [m] a car read this close has the view's edge a few metres on (the exit)
        self.exit_rate = exit_rate        # [m/s] readings opening faster than traffic moves apart: leaving the view
        self.closest = np.inf             # [m] the nearest reading of the present stretch of near readings
        self.exited = False               # the carried car left the view at its side (held until the mirror has it)
        self.seen: deque[tuple[int, float]] = deque(maxlen=window)   # (frame, gap) of the last near readings
        self.carried: tuple[int, float, float] | None = None          # (frame, gap, closing rate) when lost
        self.lost_speed: float | None = None   # [m/s] the host's speed at the car's last near reading (None: not given)
        self.predicted = 0.0                   # [m] the carried gap now (with the host's speed)
        self.steady = 0.0                      # [m] the carried gap now at the seen closing rate alone
        self.seen_speed: float | None = None   # [m/s] the host's speed at the last near reading
        self.frame = 0

    def reset(self) -> None:
        self.seen.clear()
        self.carried = None
        self.closest = np.inf

    def closing_rate(self) -> float:
        """[m/s] how fast the gap shrank over the near readings (least-squares slope, positive when closing)."""
        frames, gaps = np.array(self.seen).T
        return float(-np.polyfit((frames - frames[-1]) * FRAME_S, gaps, 1)[0])

    def _closing(self, speed: float | None) -> float:
        """[m/s] how fast the carried car's gap shrinks now: its seen rate plus what the host gained on it since."""
        assert self.carried is not None
        gained = 0.0 if speed is None or self.lost_speed is None else speed - self.lost_speed
        return self.carried[2] + gained

    def filter(self, gap: float, speed: float | None = None, behind_seen: bool | None = None) -> float:
        """The gap the controller should read this frame, from the estimate `gap` [m] and the host's `speed` [m/s]
        (optional: without it a carried car closes at its seen rate throughout). `behind_seen`, for a driver that
        also reads the mirror: whether the rear view has a car near behind in this lane now; False keeps a car
        that the reckoning has behind as alongside (the hand-over, below), None leaves the reckoning alone."""
        self.frame += 1
        if self.carried is not None:   # a carried car moves on every frame, seen again or not
            self.predicted -= self._closing(speed) * FRAME_S
            self.steady -= self.carried[2] * FRAME_S
        if gap < self.near:
            if self.seen and self.seen[-1][0] != self.frame - 1:
                self.seen.clear()             # not the same stretch of readings
                self.closest = np.inf
            self.seen.append((self.frame, gap))
            self.closest = min(self.closest, gap)
            self.seen_speed = speed
            return gap                        # a carried car stays carried: a flickering reading does not end it
        if self.carried is None and len(self.seen) >= self.min_seen and self.seen[-1][0] == self.frame - 1:
            rate = self.closing_rate()
            self.exited = behind_seen is not None and self.closest < self.beside and rate < -self.exit_rate
            if rate > self.min_closing or self.exited:
                self.carried = (self.seen[-1][0], self.seen[-1][1], rate)
                self.lost_speed = self.seen_speed
                self.predicted = self.seen[-1][1] - self._closing(speed) * FRAME_S   # one frame on
                self.steady = self.seen[-1][1] - rate * FRAME_S
        self.seen.clear()
        self.closest = np.inf
        if self.carried is not None:
            in_time = self.frame - self.carried[0] <= round(self.max_s / FRAME_S)
            if self.exited:   # beside the host until the mirror has it
                if in_time and not behind_seen:
                    return 0.0
            else:
                behind = -self.clear_behind >= max(self.predicted, self.steady)   # clear behind by both reckonings
                behind = behind and behind_seen is not False   # ... and, with a mirror, in its view (the hand-over)
                if not behind and self.predicted < self.near and in_time:
                    return max(self.predicted, 0.0)    # alongside or just behind: the lane is still taken
            self.carried = None
        return gap
