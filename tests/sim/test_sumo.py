"""SUMO traffic with a real SUMO (libsumo in this process, a sumo process over TraCI beside it, networks from
netconvert)."""
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from core.worlds.highway import Action
from sim.collision import overlaps
from sim.highway.errors import TrafficError
from sim.highway.sumo_network import network_for
from sim.highway.world import World, WorldConfig
from sim.track import load_track


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DRIVESTUDIO_CACHE", str(tmp_path / "cache"))


def hold_lane(obs, target_d: float, speed: float) -> Action:
    """Test driver: keep a lateral offset at a speed (a P controller on the true pose)."""
    ind = obs.truth.indicators
    steer = (ind[0] - (obs.truth.ego[4] - target_d) / 8.0) / 0.541052
    v = obs.truth.speed
    return Action(float(np.clip(steer, -1, 1)), 0.5 if v < speed else 0.0, 0.3 if v > speed + 1 else 0.0)


@pytest.mark.parametrize("name, lanes", [("oval", 3), ("hairpins", 2), ("sbends", 1), ("ring", 4)])
def test_sumo_lanes_follow_the_track_lane_centres(name, lanes):
    track = load_track(name, lanes=lanes)
    net = network_for(track)
    root = ET.parse(net.path).getroot()
    worst = 0.0
    n_lanes = 0
    for lane in root.iter("lane"):
        k = lanes - 1 - int(lane.get("index"))  # SUMO's lane 0 is the rightmost
        pts = np.array([[float(v) for v in p.split(",")] for p in lane.get("shape").split()])
        _, d = track.frenet(pts[:, 0], pts[:, 1])
        worst = max(worst, float(np.abs(d - track.lane_centres[k]).max()))
        n_lanes += 1
    assert n_lanes == lanes * len(net.edges)
    assert worst < 0.03


def test_network_is_cached_and_no_temporary_files_remain(tmp_path):
    track = load_track("oval", lanes=2)
    a = network_for(track)
    mtime = a.path.stat().st_mtime_ns
    b = network_for(track)
    assert a.path == b.path and b.path.stat().st_mtime_ns == mtime
    leftovers = [p.name for p in (tmp_path / "cache" / "sumo").iterdir() if p.name.startswith(".")]
    assert leftovers == []


def test_failed_netconvert_is_a_clear_error_and_leaves_nothing(tmp_path, monkeypatch):
    import sim.highway.sumo_network as sn
    monkeypatch.setattr(sn, "_netconvert", lambda: "/bin/false")
    with pytest.raises(TrafficError, match="SUMO cannot build a network for track 'oval'"):
        network_for(load_track("oval", lanes=3))
    assert list((tmp_path / "cache" / "sumo").iterdir()) == []


@pytest.mark.parametrize("cars", [-1, 301, 2.5])
def test_car_count_out_of_range(cars):
    with pytest.raises(TrafficError, match="number of AI cars"):
        World(WorldConfig(cars=cars, render=False))


def test_too_many_cars_for_the_track():
    with pytest.raises(TrafficError, match="do not fit"):
        World(WorldConfig(track="ring", lanes=1, cars=100, render=False))


def test_a_second_world_runs_beside_the_first():
    # libsumo serves one; the second gets its own sumo process over TraCI (tests/sim/test_sumo_transports.py)
    with World(WorldConfig(cars=4, render=False)) as a, World(WorldConfig(cars=4, render=False)) as b:
        assert a.step([0.0, 0.0, 0.0]).t == b.step([0.0, 0.0, 0.0]).t
    World(WorldConfig(cars=4, render=False)).close()  # and after closing, a new one starts


def run(seed, steps, cars=12, track="oval", lanes=3):
    poses = []
    with World(WorldConfig(track=track, lanes=lanes, cars=cars, seed=seed, render=False, start_speed=15)) as w:
        obs = w.observe()
        target = obs.truth.ego[4]
        for _ in range(steps):
            obs = w.step(hold_lane(obs, target, 15.0))
            poses.append(obs.truth.cars.copy())
    return poses


def test_same_seed_same_traffic_step_for_step():
    a, b = run(3, 300), run(3, 300)
    assert len(a) == len(b)
    for pa, pb in zip(a, b):
        np.testing.assert_array_equal(pa, pb)
    c = run(4, 300)
    assert not np.array_equal(a[-1], c[-1])


def test_ai_cars_pass_a_slow_host_car_by_changing_lanes():
    with World(WorldConfig(track="oval", lanes=3, cars=30, seed=2, render=False, start_speed=8)) as w:
        obs = w.observe()
        target = w.track.lane_centres[1]
        lanes_seen: dict[int, set] = {}
        passed_by = set()
        behind_in_my_lane = set()
        for _ in range(1500):  # 150 s at 8 m/s in the centre lane
            obs = w.step(hold_lane(obs, target, 8.0))
            cars = w.cars()
            gap = w.track.gap(w.ego.s, cars.s)
            lanes = w.track.lane_of(cars.d)
            for i, (g, k) in enumerate(zip(gap, lanes)):
                lanes_seen.setdefault(i, set()).add(int(k))
                if -40 < g < 0 and k == 1:
                    behind_in_my_lane.add(i)
                if i in behind_in_my_lane and 0 < g < 40 and k != 1:
                    passed_by.add(i)
            assert not obs.collision
        assert len(passed_by) >= 2, passed_by
        assert sum(len(v) > 1 for v in lanes_seen.values()) >= 3  # several cars changed lanes


@pytest.mark.long
def test_no_ai_collisions_in_ten_minutes_and_cars_keep_circulating():
    with World(WorldConfig(track="mixed", lanes=3, cars=12, seed=5, render=False, start_speed=15)) as w:
        obs = w.observe()
        target = obs.truth.ego[4]
        sumo_collisions = 0
        for step in range(6000):
            obs = w.step(hold_lane(obs, target, 15.0))
            sumo_collisions += w._traffic.collisions()
            if step % 5 == 0:
                boxes = w.cars().boxes()
                for i in range(len(boxes)):
                    assert not overlaps(boxes[i], np.delete(boxes, i, axis=0)).any(), f"AI overlap at step {step}"
        assert sumo_collisions == 0
        assert len(w.cars()) == 12
        assert obs.t == pytest.approx(600.0)


def test_poses_follow_the_conventions():
    with World(WorldConfig(track="oval", lanes=3, cars=12, seed=1, render=False, start_speed=15)) as w:
        obs = w.observe()
        target = obs.truth.ego[4]
        for _ in range(100):
            obs = w.step(hold_lane(obs, target, 15.0))
        cars = w.cars()
        tr = w.track
        _, _, tangent = tr.pose(cars.s, cars.d)
        # cars drive along the track (yaw close to the tangent), in the lane SUMO has them on
        assert np.all(np.abs((cars.yaw - tangent + np.pi) % (2 * np.pi) - np.pi) < 0.2)
        steady = np.abs(cars.d - tr.lane_centres[tr.lane_of(cars.d)]) < 0.3
        assert steady.sum() >= 6
        for i in np.flatnonzero(steady):
            assert w._traffic.lane_index(i) == tr.lane_of(cars.d[i])
        # the ground truth sees them: the poses in the truth are the cars' poses
        np.testing.assert_allclose(obs.truth.cars[:, 3], cars.s)


def test_warm_traffic_fills_several_lanes_at_believable_spacing():
    poses = run(0, 300)[-1]
    tr = load_track("oval", lanes=3)
    lanes = tr.lane_of(poses[:, 4])
    assert len(set(lanes.tolist())) == 3
    for k in range(3):
        s = np.sort(poses[lanes == k, 3])
        if len(s) > 1:
            gaps = np.diff(np.r_[s, s[0] + tr.length])
            assert gaps.min() > 5.0  # no car inside another
