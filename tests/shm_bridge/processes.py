"""Run a function of a test module in a separate Python process (the bridge's peers are real processes)."""
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def spawn(module: str, function: str, *args) -> subprocess.Popen:
    """`function(*args)` of tests.shm_bridge.`module` in a new process; its return value is the exit status."""
    code = f"import sys; from tests.shm_bridge.{module} import {function} as f; sys.exit(f(*sys.argv[1:]))"
    return subprocess.Popen([sys.executable, "-c", code, *map(str, args)], cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
