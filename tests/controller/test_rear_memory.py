"""The rear memory (controller/highway/rear_memory.py): a car seen closing in the mirror and then lost is held
alongside (gap 0, its closing speed) for as long as it takes to pass the host by `ahead` metres, at most max_s;
a car that keeps its distance or moves away, or a single reading, is not."""
import pytest

from controller.highway.rear_memory import RearMemory

FAR = (100.0, 0.0)   # the rear labels of an empty lane


def run(memory: RearMemory, readings) -> list[tuple[float, float]]:
    return [memory.filter(g, c) for g, c in readings]


def test_a_car_closing_in_and_lost_is_held_alongside_until_it_has_passed():
    seen = [(20.0 - 0.4 * k, 4.0) for k in range(10)]          # 4 m/s closing, read down to 16.4 m
    out = run(RearMemory(max_s=10.0, ahead=15.0), seen + [FAR] * 60)
    assert out[:10] == seen                                      # seen: read as it is
    held = out[10:10 + 38]                                       # 15 m at 4 m/s: 3.75 s, 38 frames
    assert held == [(0.0, 4.0)] * 38                             # alongside, closing as seen
    assert out[10 + 38:] == [FAR] * 22                           # passed: the front camera has it


def test_the_closing_speed_held_is_the_mean_of_the_seen_estimates():
    seen = [(15.0, 2.0), (14.0, 4.0), (13.0, 6.0)]
    out = run(RearMemory(), seen + [FAR])
    assert out[-1] == (0.0, pytest.approx(4.0))


def test_max_s_bounds_the_hold_of_a_slow_car():
    seen = [(10.0, 0.5)] * 5                                     # 0.5 m/s: 30 s to pass by 15 m
    out = run(RearMemory(max_s=2.0), seen + [FAR] * 30)
    assert out[5:5 + 20] == [(0.0, 0.5)] * 20 and out[5 + 20:] == [FAR] * 10


def test_a_car_keeping_its_distance_or_moving_away_is_not_held():
    for closing in (-2.0, 0.0, 0.2):                             # opening, steady, slower than min_closing 0.3
        out = run(RearMemory(), [(12.0, closing)] * 10 + [FAR] * 5)
        assert out[10:] == [FAR] * 5


def test_a_far_car_or_a_short_sighting_is_not_held():
    assert run(RearMemory(near=25.0), [(30.0, 5.0)] * 10 + [FAR])[-1] == FAR     # never nearer than `near`
    assert run(RearMemory(), [FAR, (10.0, 5.0), (9.0, 5.0), FAR]) == [FAR, (10.0, 5.0), (9.0, 5.0), FAR]


def test_a_near_reading_while_held_does_not_free_the_lane():
    """A car alongside is misread as a car some metres behind (26.8 m in a crash clip): while held, the lookout
    reads the smaller gap and the larger closing speed."""
    memory = RearMemory()
    run(memory, [(16.0, 5.0)] * 5 + [FAR])
    assert memory.filter(20.0, 1.0) == (0.0, 5.0)
    assert memory.filter(*FAR) == (0.0, 5.0)


def test_reset_forgets_the_car():
    memory = RearMemory()
    run(memory, [(16.0, 5.0)] * 5)
    memory.reset()
    assert memory.filter(*FAR) == FAR
