"""The observation kinds and the reward terms of both environments, as docs/gymnasium.md states them."""
import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401  registers the environments

# docs/gymnasium.md: the affordance vector, field by field
HIGHWAY_FIELDS = ("angle", "toMarking_LL", "toMarking_ML", "toMarking_MR", "toMarking_RR", "dist_LL", "dist_MM",
                  "dist_RR", "toMarking_L", "toMarking_M", "toMarking_R", "dist_L", "dist_R", "fast", "speed")
SIDEWALK_FIELDS = ("steer", "motor", "behaviour", "speed", "d", "heading", "path_width", "curvature",
                   "curvature_ahead", "border_left", "border_right", "obstacle_gap", "obstacle_d", "obstacle_width",
                   "lead_gap", "lead_d", "lead_speed", "obstacle_near")


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DRIVESTUDIO_CACHE", str(tmp_path / "cache"))


def highway(**kw):
    return gym.make("drivestudio/Highway-v0", **{"track": "oval", "lanes": 3, "cars": 12, **kw})


def test_highway_affordances_are_the_indicators_then_the_speed():
    env = highway(observation="affordances")
    try:
        obs, info = env.reset(seed=4)
        assert obs.shape == (15,) and obs.dtype == np.float32
        for _ in range(30):
            obs, _, _, _, info = env.step(np.array([0.0, 0.6, 0.0], np.float32))
        for i, name in enumerate(HIGHWAY_FIELDS):
            assert obs[i] == pytest.approx(info[name], abs=1e-4), name
        assert obs[-1] > 15.0                       # the speed, accelerating from 15 m/s
        assert env.render().shape == (210, 280, 3)  # rendered on demand only
    finally:
        env.close()


def test_highway_both_holds_the_frame_and_the_affordances():
    env = highway(observation="both", width=96, height=72)
    try:
        obs, info = env.reset(seed=4)
        assert set(obs) == {"front", "affordances"}
        assert obs["front"].shape == (72, 96, 3) and obs["front"].dtype == np.uint8 and obs["front"].any()
        assert obs["affordances"][HIGHWAY_FIELDS.index("dist_MM")] == pytest.approx(info["dist_MM"], abs=1e-4)
    finally:
        env.close()


def test_sidewalk_affordances_in_the_documented_order():
    env = gym.make("drivestudio/Sidewalk-v0", mode="follow", observation="affordances")
    try:
        obs, info = env.reset(seed=2)
        for _ in range(20):
            obs, _, _, _, info = env.step(np.array([0.5, 0.8], np.float32))
        assert obs.shape == (len(SIDEWALK_FIELDS),)
        for i, name in enumerate(SIDEWALK_FIELDS):
            assert obs[i] == pytest.approx(float(info[name]), abs=1e-4), name
        assert obs[SIDEWALK_FIELDS.index("behaviour")] == 1.0     # follow is mode 1
        assert obs[SIDEWALK_FIELDS.index("speed")] > 0.5         # motor 0.8 drives forward
    finally:
        env.close()


def test_sidewalk_both_has_each_camera_by_name():
    env = gym.make("drivestudio/Sidewalk-v0", observation="both", width=84, height=47)
    try:
        obs, _ = env.reset(seed=2)
        assert set(obs) == {"left", "right", "affordances"}
        assert obs["left"].shape == obs["right"].shape == (47, 84, 3)
        assert not np.array_equal(obs["left"], obs["right"])     # a stereo pair, not one image twice
    finally:
        env.close()


def test_highway_reward_terms():
    env = highway(observation="affordances", cars=0)
    try:
        env.reset(seed=1)
        _, reward, _, _, info = env.step(np.array([0.0, 0.5, 0.0], np.float32))
        terms = info["reward_terms"]
        assert reward == pytest.approx(sum(terms.values()))
        assert terms["progress"] == pytest.approx(15.0 * 0.1, rel=0.1)   # 15 m/s for 0.1 s, forward: positive
        assert terms["collision"] == 0.0 and terms["off_road"] == 0.0
        for _ in range(200):                                               # full lock left: off the road
            _, reward, terminated, _, info = env.step(np.array([1.0, 0.3, 0.0], np.float32))
            if info["off_road"]:
                break
        assert info["off_road"] and info["reward_terms"]["off_road"] == -5.0
        assert reward == pytest.approx(sum(info["reward_terms"].values()))
        assert info["reward_terms"]["lost"] == 0.0
        for _ in range(200):                                               # on, until lost: the episode ends
            _, reward, terminated, _, info = env.step(np.array([1.0, 0.3, 0.0], np.float32))
            if terminated:
                break
        assert terminated and info["reward_terms"]["lost"] == -50.0 and info["reward_terms"]["off_road"] == -5.0
    finally:
        env.close()


def test_sidewalk_reward_terms():
    env = gym.make("drivestudio/Sidewalk-v0", observation="affordances", obstacles=0.0)
    try:
        env.reset(seed=3)
        _, reward, _, _, info = env.step(np.array([0.5, 1.0], np.float32))
        for _ in range(30):
            _, reward, _, _, info = env.step(np.array([0.5, 1.0], np.float32))
        terms = info["reward_terms"]
        assert terms["progress"] > 0 and reward == pytest.approx(sum(terms.values()))
        for _ in range(30):                                                # reverse: progress turns negative
            _, reward, _, _, info = env.step(np.array([0.5, 0.0], np.float32))
        assert info["reward_terms"]["progress"] < 0
    finally:
        env.close()


def test_bounds_hold_the_values_of_normal_driving_unclipped():
    # the Box bounds clip only a car far off its road: an oracle lap on four lanes and a sidewalk run never touch them
    from controller.highway import ChenController
    from core.worlds.highway import HIGHWAY
    from core.worlds.sidewalk import SIDEWALK
    from sim.highway.gym_env import AFFORDANCES as HIGHWAY_VIEW
    from sim.sidewalk.gym_env import AFFORDANCES as SIDEWALK_VIEW
    env = gym.make("drivestudio/Highway-v0", track="hairpins", lanes=4, cars=30, observation="affordances")
    try:
        _, info = env.reset(seed=0)
        ctrl = ChenController(4)
        for _ in range(300):
            a = ctrl.act(info["indicators"], info["speed"])
            _, _, terminated, _, info = env.step(np.array([a.steer, a.accel, a.brake], np.float32))
            raw = np.array([info[n] for n in HIGHWAY.observable])
            assert (raw >= HIGHWAY_VIEW.low).all() and (raw <= HIGHWAY_VIEW.high).all()
            if terminated:   # a collision in dense traffic: drive on in the next episode
                _, info = env.reset()
                ctrl = ChenController(4)
    finally:
        env.close()
    env = gym.make("drivestudio/Sidewalk-v0", mode="follow", observation="affordances")
    try:
        env.reset(seed=0)
        for k in range(300):
            _, _, terminated, _, info = env.step(np.array([0.5 + 0.1 * np.sin(k / 20), 0.75], np.float32))
            raw = SIDEWALK.values(info["record"], SIDEWALK.observable)
            assert (raw >= SIDEWALK_VIEW.low).all() and (raw <= SIDEWALK_VIEW.high).all()
            if terminated:
                break
    finally:
        env.close()
