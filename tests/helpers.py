"""Running `drivestudio VERB ...` inside the test process: the command line's entry point with captured streams.

A refusal or an option check needs no interpreter of its own: `drivestudio.cli.main(argv)` returns the exit status
(argparse's errors leave by SystemExit, caught here) and the streams are read at the file-descriptor level, so what
a library writes there counts as it would in a real run. Warnings a real run would print on stderr are put there
too (pytest would otherwise keep them to itself), so "one line on stderr" means the same as from a shell.

The contracts only a real process can show (exit statuses of signals and crashes, a killed peer, a second
interpreter's state) keep their subprocess tests.
"""
from __future__ import annotations

import os
import signal
import struct
import sys
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

# the categories Python's default filters keep quiet in a program's own run
_QUIET = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)
_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGPIPE)


@dataclass
class Run:
    """What subprocess.run would have given: the exit status and the two streams as text."""
    returncode: int
    stdout: str
    stderr: str


@contextmanager
def _worlds_kept():
    """The worlds a run learnt from DRIVESTUDIO_WORLDS are forgotten afterwards: the next run in this process sees
    the worlds a fresh interpreter would."""
    from core import worlds as declarations
    from drivestudio import worlds
    kept = [(registry, set(registry._REGISTERED), set(registry._modules())) for registry in (worlds, declarations)]
    try:
        yield
    finally:
        for registry, before, built_in in kept:
            for name in set(registry._REGISTERED) - before - built_in:
                del registry._REGISTERED[name]


def run_main(capfd, *argv, cwd: str | Path | None = None, env: dict[str, str] | None = None, entry=None) -> Run:
    """`drivestudio *argv` in this process, in `cwd`, with `env` added to the environment; everything it changed
    (cwd, environment, the worlds it learnt, signal handlers, torch's thread count) is put back afterwards. `entry`:
    another tool's main(argv) (`drivestudio ensemble`'s), instead of drivestudio's."""
    from drivestudio.cli import main
    main = entry or main
    capfd.readouterr()                      # what came before is not this run's
    old_cwd = os.getcwd()
    old_env = dict(os.environ)
    old_handlers = {s: signal.getsignal(s) for s in _SIGNALS}
    torch = sys.modules.get("torch")
    threads = torch.get_num_threads() if torch is not None else None
    printed: list[str] = []
    try:
        if cwd is not None:
            os.chdir(cwd)
        os.environ.update(env or {})
        with _worlds_kept(), warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("default")
            try:
                code = main([str(a) for a in argv])
            except SystemExit as e:       # argparse: a usage error (2) or --help (0)
                code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
                if isinstance(e.code, str):
                    print(e.code, file=sys.stderr)
        printed = [warnings.formatwarning(w.message, w.category, w.filename, w.lineno, w.line)
                   for w in caught if not issubclass(w.category, _QUIET)]
    finally:
        os.chdir(old_cwd)
        os.environ.clear()
        os.environ.update(old_env)
        for s, h in old_handlers.items():
            if h is not None:
                signal.signal(s, h)
        torch = sys.modules.get("torch")
        if torch is not None and threads is not None and torch.get_num_threads() != threads:
            torch.set_num_threads(threads)
    sys.stdout.flush()
    sys.stderr.flush()
    out, err = capfd.readouterr()
    return Run(code, out, err + "".join(printed))


def make(*argv, env: dict[str, str] | None = None) -> None:
    """`drivestudio *argv` in this process for a fixture's data or model (a session's or a module's: no capfd
    there), with `env` added to the environment meanwhile; it must succeed."""
    from drivestudio.cli import main
    old_env = dict(os.environ)
    try:
        os.environ.update(env or {})
        with _worlds_kept():
            code = main([str(a) for a in argv])
    finally:
        os.environ.clear()
        os.environ.update(old_env)
    assert code == 0, f"drivestudio {' '.join(map(str, argv))} exited with {code}"


def driven_frames(name: str) -> int:
    """driver_seen_seq of the bridge segment /dev/shm/NAME (shm_bridge/layout.py: the newest frame its driver has
    taken), read from outside; 0 while the segment is not ready or gone. A run that shows frames here is driving."""
    try:
        with open(f"/dev/shm/{name}", "rb") as f:
            head = f.read(224)
    except FileNotFoundError:
        return 0
    return struct.unpack_from("=Q", head, 216)[0] if len(head) == 224 and head[:8] == b"DSBRIDGE" else 0
