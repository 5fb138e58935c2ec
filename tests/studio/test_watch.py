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


def test_a_stall_stays_in_the_measure_for_a_whole_window_after_the_loop_runs_again():
    """A loop stopped for 1.5 s (a starved process) reads behind for the second after it runs again, every step of
    it, not for one step the page may never be sent; a second later it keeps up."""
    from drivestudio.studio.watch import RATE_WINDOW, RateMeter
    clock = [0.0]
    meter = RateMeter(clock=lambda: clock[0])
    t = 0.0
    for n in range(20):                     # 2 s in real time
        clock[0], t = 0.1 * n, 0.1 * n
        meter.tick(t)
    resumed = clock[0] + 1.5                # the stall
    rates = []
    for n in range(1, 21):
        clock[0], t = resumed + 0.1 * n, t + 0.1
        meter.tick(t)
        rates.append((clock[0] - resumed, meter.sim_rate))
    assert all(r < BEHIND for dt, r in rates if dt < RATE_WINDOW - 1e-9)
    assert all(abs(r - 1.0) < 1e-6 for dt, r in rates if dt > RATE_WINDOW + 0.1 + 1e-9)
