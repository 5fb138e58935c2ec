"""The pass memory (controller/highway/pass_memory.py): a neighbour car closing at a steady rate and then lost by the
camera is carried on at that rate until it is clear behind the host; nothing else is changed."""
import pytest

from controller.highway.pass_memory import PassMemory

FAR = 60.0


def run(memory: PassMemory, gaps) -> list[float]:
    return [memory.filter(g) for g in gaps]


def test_a_car_being_passed_is_carried_on_at_its_closing_rate_until_clear_behind():
    seen = [16.0 - 0.2 * k for k in range(30)]              # 2 m/s closing, seen down to 10.2 m
    out = run(PassMemory(clear_behind=10.0), seen + [FAR] * 120)
    assert out[:30] == seen                                  # seen: read as it is
    ahead = out[30:30 + 51]
    assert ahead[0] == pytest.approx(10.0, abs=0.05)         # one frame on: 10.2 - 0.2
    assert all(a > b for a, b in zip(ahead, ahead[1:]))      # closing all the way to level (5.1 s on)
    assert ahead[-1] == pytest.approx(0.0, abs=0.25)
    assert out[30 + 52:30 + 100] == [0.0] * 48               # alongside and behind: the lane is taken
    assert out[30 + 102:] == [FAR] * 18                      # 10 m behind (10.1 s on): free again


def test_a_car_moving_away_or_keeping_its_distance_is_not_carried():
    for rate in (-1.0, 0.0, 0.1):                            # opening, steady, too slow to be passed
        out = run(PassMemory(), [12.0 - rate * 0.1 * k for k in range(20)] + [FAR] * 5)
        assert out[20:] == [FAR] * 5


def test_a_single_near_reading_is_noise_not_a_car():
    assert run(PassMemory(), [FAR, 8.0, 7.0, FAR, FAR]) == [FAR, 8.0, 7.0, FAR, FAR]


def test_the_carried_car_ends_after_max_s_and_survives_a_flickering_reading():
    out = run(PassMemory(max_s=1.0), [19.0 - 0.05 * k for k in range(20)] + [FAR] * 30)   # 0.5 m/s: 36 s to level
    assert all(g < 20.0 for g in out[20:30]) and out[31:] == [FAR] * 19
    memory = PassMemory()
    run(memory, [15.0 - 0.2 * k for k in range(10)] + [FAR] * 3)
    assert memory.filter(9.0) == 9.0                         # seen again: the reading itself
    assert memory.filter(FAR) == pytest.approx(13.2 - 0.2 * 5, abs=0.05)   # lost again: still carried


def test_reset_forgets_the_car():
    memory = PassMemory()
    run(memory, [15.0 - 0.2 * k for k in range(10)])
    memory.reset()
    assert memory.filter(FAR) == FAR


def test_a_host_that_slows_down_keeps_the_car_alongside_longer():
    """The carried gap closes at the seen rate plus what the host gained since: after losing a car closing at
    2 m/s, a host 1.5 m/s slower closes at 0.5 m/s, so the car is still 4.2 m ahead 12 s on (10.2 - 0.5 x 12),
    where the seen rate alone had it 13.8 m behind and the lane free."""
    seen = [16.0 - 0.2 * k for k in range(30)]
    memory = PassMemory(max_s=30.0)
    out = [memory.filter(g, 20.0) for g in seen] + [memory.filter(FAR, 18.5) for _ in range(120)]
    assert out[30] == pytest.approx(10.2 - 0.05, abs=0.01)       # one frame on at 0.5 m/s
    assert out[149] == pytest.approx(10.2 - 0.5 * 12.0, abs=0.01)
    assert run(PassMemory(max_s=30.0), seen + [FAR] * 120)[149] == FAR   # without the speed: gone at 10.1 s


def test_a_host_that_speeds_up_passes_sooner_and_one_that_falls_back_lets_the_car_ahead_go():
    seen = [16.0 - 0.2 * k for k in range(30)]
    faster = PassMemory()
    [faster.filter(g, 20.0) for g in seen]
    assert faster.filter(FAR, 22.0) == pytest.approx(10.2 - 0.4, abs=0.01)   # closing at 4 m/s
    slower = PassMemory()
    [slower.filter(g, 20.0) for g in seen]
    out = [slower.filter(FAR, 15.0) for _ in range(40)]         # 3 m/s opening: ahead again, beyond 20 m in 3.3 s
    assert out[0] == pytest.approx(10.2 + 0.3, abs=0.01) and out[-1] == FAR


def test_a_host_that_speeds_up_gives_the_lane_up_only_when_the_seen_rate_has_the_car_clear_behind_too():
    """Traffic often speeds up with the host: a car lost at 10.2 m closing at 2 m/s, the host then 2 m/s faster,
    is 10 m behind after 5.05 s by the host's speed (4 m/s) but only after 10.1 s at the rate it was seen closing;
    the lane stays taken until both say so."""
    seen = [16.0 - 0.2 * k for k in range(30)]
    memory = PassMemory(max_s=30.0)
    [memory.filter(g, 20.0) for g in seen]
    out = [memory.filter(FAR, 22.0) for _ in range(120)]
    assert out[0] == pytest.approx(10.2 - 0.4, abs=0.01)        # the gap read is the host-speed reckoning
    assert out[50:100] == [0.0] * 50                            # past -10 m by it (5.1 s on), still taken
    assert out[102:] == [FAR] * 18                              # at the seen rate 10 m behind too: free


def test_with_a_mirror_a_passed_car_is_given_up_only_once_the_rear_view_has_it():
    """The hand-over: the reckoning has the car 10 m behind 10.1 s after it was lost (the first test); while the
    rear view reads nothing near behind it is still alongside, and the lane is free on the first frame it does."""
    seen = [16.0 - 0.2 * k for k in range(30)]
    memory = PassMemory(clear_behind=10.0, max_s=30.0)
    out = [memory.filter(g) for g in seen] + [memory.filter(FAR, None, False) for _ in range(150)]
    assert out[30 + 102:] == [0.0] * 48                       # behind by the reckoning, not in the mirror: taken
    assert memory.filter(FAR, None, True) == FAR              # the mirror has it: free
    plain = PassMemory(clear_behind=10.0, max_s=30.0)
    assert [plain.filter(g, None, None) for g in seen + [FAR] * 150][30 + 102:] == [FAR] * 48   # no mirror: as before


def test_the_hand_over_never_outlasts_max_s():
    memory = PassMemory(max_s=5.0)
    out = [memory.filter(g) for g in [16.0 - 0.2 * k for k in range(30)]]
    out += [memory.filter(FAR, None, False) for _ in range(60)]
    assert out[30:30 + 50] != [FAR] * 50 and out[30 + 51:] == [FAR] * 9


EXIT = [6.0, 3.0, 1.0, 2.0, 4.0, 7.0, 10.0, 13.0, 16.0, 19.0]   # near, then opening at 30 m/s: the view's edge


def test_with_a_mirror_a_car_leaving_the_view_at_its_side_is_beside_the_host_until_the_mirror_has_it():
    memory = PassMemory(max_s=15.0)
    out = [memory.filter(g, None, False) for g in EXIT] + [memory.filter(FAR, None, False) for _ in range(50)]
    assert out[len(EXIT):] == [0.0] * 50                      # lost while opening faster than traffic: beside
    assert memory.filter(FAR, None, True) == FAR              # the mirror has it: free


def test_a_car_pulling_away_or_one_never_near_is_not_taken_for_a_view_exit():
    away = [5.0 + 0.3 * k for k in range(50)]                  # 3 m/s: traffic moving apart, still in view
    memory = PassMemory()
    assert [memory.filter(g, None, False) for g in away + [FAR] * 5][50:] == [FAR] * 5
    far_exit = [12.0 + 3.0 * k for k in range(3)]              # opening fast, but never nearer than 8 m
    memory = PassMemory()
    assert [memory.filter(g, None, False) for g in far_exit + [FAR] * 5][3:] == [FAR] * 5
    plain = PassMemory()                                       # no mirror: nothing could ever release it
    assert [plain.filter(g) for g in EXIT + [FAR] * 5][len(EXIT):] == [FAR] * 5


def test_a_view_exit_is_held_at_most_max_s():
    memory = PassMemory(max_s=2.0)
    out = [memory.filter(g, None, False) for g in EXIT] + [memory.filter(FAR, None, False) for _ in range(30)]
    assert out[len(EXIT):len(EXIT) + 20] == [0.0] * 20 and out[len(EXIT) + 22:] == [FAR] * 8
