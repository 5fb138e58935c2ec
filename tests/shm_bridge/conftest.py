"""Shared by the bridge tests: a fresh segment name that must be gone when the test ends."""
import os
import uuid

import pytest


@pytest.fixture
def name():
    n = f"dstest-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    yield n
    path = f"/dev/shm/{n}"
    leaked = os.path.exists(path)
    if leaked:
        os.unlink(path)
    assert not leaked, f"{path} was left behind"
