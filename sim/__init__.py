"""The world: tracks, scenes, cameras, ego dynamics, SUMO traffic and ground truth."""
try:  # the Gymnasium id; the environment module itself loads only on gymnasium.make
    from gymnasium.envs.registration import register as _register

    _register(id="drivestudio/Highway-v0", entry_point="sim.highway.gym_env:HighwayEnv")
    _register(id="drivestudio/Sidewalk-v0", entry_point="sim.sidewalk.gym_env:SidewalkEnv")
except ImportError:  # pragma: no cover - gymnasium is a declared dependency
    pass
