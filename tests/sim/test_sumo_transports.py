"""Many highway worlds in one process: the first runs SUMO in-process (libsumo), the others each their own sumo
process over TraCI (sim/highway/sumo_connection.py), with the same traffic for the same seed."""
import numpy as np
import pytest

from sim.highway.errors import TrafficError
from sim.highway.sumo_connection import libsumo_free
from sim.highway.world import World, WorldConfig
from tests.sim.sumo_processes import sumo_children
from tests.sim.test_sumo import hold_lane


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DRIVESTUDIO_CACHE", str(tmp_path / "cache"))


def config(seed: int, sumo: str = "auto", cars: int = 12) -> WorldConfig:
    return WorldConfig(track="oval", lanes=3, cars=cars, seed=seed, render=False, start_speed=15, sumo=sumo)


def test_same_seed_same_traffic_over_libsumo_and_traci():
    # both open at once: libsumo cannot serve two, so this is also the two-worlds-in-one-process case
    with World(config(5, "libsumo")) as a, World(config(5, "traci")) as b:
        assert (a._traffic.transport, b._traffic.transport) == ("libsumo", "traci")
        oa, ob = a.observe(), b.observe()
        target = oa.truth.ego[4]
        for _ in range(200):
            act = hold_lane(oa, target, 15.0)
            oa, ob = a.step(act), b.step(act)
            np.testing.assert_array_equal(oa.truth.cars, ob.truth.cars)
            np.testing.assert_array_equal(oa.record, ob.record)
        np.testing.assert_array_equal(a.cars().poses(), b.cars().poses())   # all 12, not only those in view
        assert len(a.cars()) == 12
        assert len(sumo_children()) == 1      # the TraCI world's sumo; libsumo has none
    assert sumo_children() == [] and libsumo_free()


def test_eight_worlds_in_one_process_each_with_its_own_traffic():
    worlds = [World(config(seed)) for seed in range(8)]
    try:
        assert [w._traffic.transport for w in worlds] == ["libsumo"] + ["traci"] * 7
        assert len(sumo_children()) == 7
        start = [w.cars().poses() for w in worlds]
        for _ in range(20):
            for w in worlds:
                w.step(np.array([0.0, 0.3, 0.0]))
        cars = [w.cars() for w in worlds]
        for s0, c in zip(start, cars):
            # SUMO may hold back a car whose start slot is not yet free; the others move, in every world
            assert len(c) >= 8
            assert c.poses().shape != s0.shape or not np.allclose(c.poses(), s0)
        assert len({c.poses().tobytes() for c in cars}) == 8          # eight seeds, eight traffics
    finally:
        for w in worlds:
            w.close()
    assert sumo_children() == [] and libsumo_free()


def test_libsumo_is_one_at_a_time_and_freed_on_close():
    with World(config(1, cars=4)):
        with pytest.raises(TrafficError, match="libsumo already runs a simulation"):
            World(config(1, "libsumo", cars=4))
    with World(config(1, cars=4)) as w:   # freed: the next auto world gets libsumo again
        assert w._traffic.transport == "libsumo"


def test_unknown_transport_is_one_clear_error():
    with pytest.raises(TrafficError, match="unknown SUMO transport 'pipes'"):
        World(config(1, "pipes", cars=4))
    assert sumo_children() == [] and libsumo_free()


def test_a_world_dropped_without_close_ends_its_sumo_process():
    keep = World(config(2, cars=4))
    w = World(config(3, cars=4))
    assert w._traffic.transport == "traci" and len(sumo_children()) == 1
    del w   # garbage: its finaliser ends the process
    import gc
    gc.collect()
    assert sumo_children() == []
    keep.close()
