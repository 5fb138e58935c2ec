"""A driver endpoint still tells why the world ended the run after it has closed: it keeps the reason it read
when it closed, not the "none" of a run that never ended."""
from __future__ import annotations

import numpy as np

from shm_bridge.endpoints import DriverEndpoint, WorldEndpoint
from tests.shm_bridge.records import TRUTH_LEN, small


def test_the_end_reason_outlives_the_drivers_close(name):
    world = WorldEndpoint(name, small(2, 2))
    try:
        with DriverEndpoint(name, attach_timeout=1) as driver:
            world.publish(np.zeros((2, 2, 3), dtype=np.uint8), np.zeros(TRUTH_LEN))
            world.end("host lost")
            assert driver.wait_frame(timeout=1) is not None
            assert driver.wait_frame(timeout=1) is None
        assert driver.closed
        assert driver.end_reason == "host lost"
    finally:
        world.close()
