"""What every page sees of a run, the studio's or one watched with --view: the step's state (time, command, labels,
controller, metrics, loop rate) beside the view's images, handed to the publisher when a page is ready for them.
"""
from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable

import numpy as np

from drivestudio.loop import StepRecord
from drivestudio.studio.kit import finite
from drivestudio.studio.publisher import Publisher, Snapshot

METRICS_EVERY = 0.25     # [s] the metrics' report is refreshed this often (it grows with the run)
RATE_WINDOW = 1.0        # [s] the loop rate is measured over this much wall-clock time
BEHIND = 0.9             # a real-time loop that runs slower than this fraction of real time is behind


class RateMeter:
    """Steps, and simulated seconds, per wall-clock second over the last RATE_WINDOW seconds."""

    def __init__(self, clock: Callable[[], float] = time.perf_counter):
        self._marks: deque[tuple[float, int, float]] = deque()
        self.steps = 0
        self.clock = clock

    def tick(self, t: float = 0.0) -> None:
        """One step, whose simulated time is t [s]."""
        self.steps += 1
        now = self.clock()
        self._marks.append((now, self.steps, t))
        # the oldest mark kept is the last one at or before the window's start, so that a stall (a busy CPU)
        # stays in the measure for a whole window after the loop runs again, not for one step
        while len(self._marks) > 2 and now - self._marks[1][0] >= RATE_WINDOW:
            self._marks.popleft()

    def restart(self) -> None:
        """Forget the marks: a pause, a new world (a wait that is not the loop's slowness)."""
        self._marks.clear()

    @property
    def hz(self) -> float:
        if len(self._marks) < 2:
            return 0.0
        (t0, n0, _), (t1, n1, _) = self._marks[0], self._marks[-1]
        return (n1 - n0) / (t1 - t0) if t1 > t0 else 0.0

    @property
    def sim_rate(self) -> float | None:
        """Simulated seconds per wall-clock second (1: real time), or None before two steps."""
        if len(self._marks) < 2:
            return None
        (w0, _, t0), (w1, _, t1) = self._marks[0], self._marks[-1]
        return (t1 - t0) / (w1 - w0) if w1 > w0 else None


class Watch:
    """One run's publication: `step(rec, ...)` on every step of the loop."""

    def __init__(self, publisher: Publisher, view, metrics=None):
        self.publisher, self.view, self.metrics = publisher, view, metrics
        self.rate = RateMeter()
        self._report: dict = {}
        self._report_at = -1.0
        self.last: StepRecord | None = None
        self._last_published: StepRecord | None = None

    def restart(self, view, metrics) -> None:
        """A new world (a reset): its view and metrics."""
        self.view, self.metrics = view, metrics
        self.rate.restart()
        self._report, self._report_at = {}, -1.0

    def _metrics(self) -> dict:
        now = time.perf_counter()
        if self.metrics is not None and now - self._report_at >= METRICS_EVERY:
            self._report = self.view.metrics(self.metrics.report())
            self._report_at = now
        return self._report

    def behind(self, extra: dict) -> float | None:
        """The simulated seconds per wall-clock second of a real-time loop that falls behind real time (a busy
        CPU, a slow driver); None while it keeps up, runs as fast as it can or is paused."""
        rate = self.rate.sim_rate
        if not extra.get("realtime") or extra.get("paused") or rate is None or rate >= BEHIND:
            return None
        return round(rate, 2)

    def state(self, rec: StepRecord, driver, supervisor, extra: dict) -> dict:
        return {"t": round(float(rec.obs.t), 4), "step": self.rate.steps,
                "command": [finite(v) for v in np.asarray(rec.action, dtype=np.float64)],
                "labels": self.view.labels(rec), "controller": self.view.controller(driver, supervisor, rec),
                "metrics": self._metrics(), "loop_hz": round(self.rate.hz, 1), "behind": self.behind(extra),
                **self.view.live(rec), **extra}

    def step(self, rec: StepRecord, driver=None, supervisor=None, extra: dict | None = None,
             name: str = "") -> None:
        """Loop thread, every step: count it and publish it if a page is ready."""
        self.rate.tick(float(rec.obs.t))
        self.last = rec
        self.publish(rec, driver, supervisor, extra or {}, name)

    def publish(self, rec: StepRecord, driver, supervisor, extra: dict, name: str) -> bool:
        view = self.view

        def make() -> Snapshot:
            return Snapshot({"seq": self.publisher.published + 1, **self.state(rec, driver, supervisor, extra)},
                            view, view.capture(rec, name))
        done = self.publisher.offer(make)
        if done:
            self._last_published = rec
        return done

    def republish(self, driver, supervisor, extra: dict, name: str, changed: bool) -> bool:
        """While paused: the last step again, when the page has not had it or something it shows changed.
        Returns whether it was published."""
        if self.last is not None and (changed or self._last_published is not self.last):
            return self.publish(self.last, driver, supervisor, extra, name)
        return False
