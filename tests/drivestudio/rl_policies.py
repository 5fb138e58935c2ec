"""Policies as plain callables for the benchmark's policy rows (tests/drivestudio/test_rl_policy.py)."""
import numpy as np

from controller.highway import ChenController

LANES = 2   # the route these drive (ROUTE_B of tests/drivestudio/test_benchmark.py)


class ChenOnAffordances:
    """The Chen controller on the affordance observation, read by its documented layout (the 14 indicators, then
    the speed): it must drive as the oracle does, which reads the same values from the truth record."""

    def __init__(self):
        self.controller = ChenController(LANES)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.controller.act(obs[:14].astype(np.float64), float(obs[14])).as_array()


chen = ChenOnAffordances()
