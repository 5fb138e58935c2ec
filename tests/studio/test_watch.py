"""What every page is told of the loop's pace (drivestudio/studio/watch.py): a real-time loop that falls behind real
time says by how much, and only then."""
from __future__ import annotations

import pytest

from drivestudio.studio.publisher import Publisher
from drivestudio.studio.watch import BEHIND, Watch


def _watch(clock: list[float]) -> Watch:
    w = Watch(Publisher(), None)
    w.rate.clock = lambda: clock[0]
    return w


def test_a_real_time_loop_that_falls_behind_says_how_far_and_only_then():
    clock = [0.0]
    w = _watch(clock)
    running = {"realtime": True, "paused": False}
    for n in range(12):            # 0.1 s steps, one every 0.4 s of wall clock: a quarter of real time
        clock[0] = 0.4 * n
        w.rate.tick(0.1 * n)
    assert w.behind(running) == 0.25
    assert w.rate.hz == pytest.approx(2.5)
    assert w.behind({"realtime": False, "paused": False}) is None     # as fast as it can: never behind
    assert w.behind({"realtime": True, "paused": True}) is None       # paused: not the loop's slowness
    w.rate.restart()
    assert w.behind(running) is None                                  # nothing measured yet
    for n in range(12):            # and in step with the wall clock again
        clock[0] = 10.0 + 0.1 * n
        w.rate.tick(2.0 + 0.1 * n)
    assert w.behind(running) is None
    for n in range(12):            # just under the threshold
        clock[0] = 20.0 + 0.1 * n / (BEHIND - 0.05)
        w.rate.tick(5.0 + 0.1 * n)
    assert w.behind(running) == round(BEHIND - 0.05, 2)
