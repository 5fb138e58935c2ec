"""What every test shares."""
import functools
import signal

import pytest

from tests.helpers import run_main

# A shell starts a background job (`pytest &`, `nohup pytest`) with SIGINT ignored, and an ignored signal stays
# ignored in every process started from it: the tests that stop a verb with SIGINT (exit status 130) would wait in
# vain. Python's own handler here lets the verbs they start begin with SIGINT at its default, as from a terminal.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture
def run_cli(capfd):
    """`run_cli("render", "-o", path, cwd=..., env=...)`: the command in this process (tests/helpers.py), returning
    its exit status and what it wrote on stdout and stderr."""
    return functools.partial(run_main, capfd)
