"""What the bridge tests publish: the highway's declaration (or the same world with tiny frames) and records."""
import numpy as np

from core.worlds.highway import HIGHWAY

TRUTH_LEN = len(HIGHWAY.truth)
ESTIMATE_LEN = len(HIGHWAY.estimate_names)


def small(height: int, width: int):
    """The highway's declaration with frames of height x width (tests need not move 176 kB a frame)."""
    return HIGHWAY.with_camera("front", height, width)


def same(action, expected) -> bool:
    """Whether an action array equals an Action (or a sequence) exactly."""
    want = expected.as_array() if hasattr(expected, "as_array") else np.asarray(expected, dtype=np.float64)
    return np.array_equal(np.asarray(action), want)
