"""Writing files so that nothing is ever damaged: the one owner of output checks and atomic replacement.

Every result a verb writes (frames, tables, checkpoints, shards, manifests, videos) goes through here:
- `check_output(path, suffixes)` runs before any work: an output that cannot be written (empty name, a folder, a
  device, FIFO or socket, a parent that cannot be created or written, a suffix the verb cannot write) is refused
  with one line (OutputError, exit status 2 in the CLI);
- `atomic_write(path, data)` writes a hidden temporary file beside the target and renames it into place, so a
  crash leaves the old file or the new one, never half of one. It never replaces something that is not a
  regular file: a symbolic link is followed deliberately (the file it points to is replaced, the link stays),
  anything else is refused;
- temporaries carry the writer's pid (`.NAME.PID.tmp`); a later write to the same place removes those whose
  process is dead, so a kill -9 during a save leaves nothing behind for long.
"""
from __future__ import annotations

import os
import re
import stat
from pathlib import Path

from core.processes import pid_alive

_TMP = re.compile(r"\.(?P<name>.+)\.(?P<pid>\d+)\.(?P<n>\d+)\.tmp(\.mp4)?$")


class OutputError(ValueError):
    """An output path that cannot or must not be written; the message is one line for the user."""


def _describe(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def resolve_target(path) -> Path:
    """The file a write to `path` replaces: `path` itself, or what its symbolic link points to."""
    path = Path(path)
    if path.is_symlink():
        return Path(os.path.realpath(path))
    return path


def _check_parent(parent: Path, shown) -> None:
    probe = parent
    while not probe.exists():
        if probe.is_symlink():  # a dangling link in the way
            raise OutputError(f"cannot write {shown}: {probe} is a broken symbolic link")
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise OutputError(f"cannot write {shown}: {probe} is not a folder")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write {shown}: {probe} is not writable")
    if str(probe).startswith(("/proc", "/sys")):
        raise OutputError(f"cannot write {shown}: {probe} is not a place for files")


def check_output(path, suffixes: tuple[str, ...] | None = None, what: str = "output") -> Path:
    """Refuse, before any work, an output file that cannot be written; returns the path.

    suffixes: the extensions the verb can write (e.g. (".png",)); others are refused."""
    if path is None or str(path).strip() == "":
        raise OutputError(f"the {what} path is empty")
    path = Path(path)
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise OutputError(f"cannot write {path}: the {what} must end in {' or '.join(suffixes)}")
    target = resolve_target(path)
    try:
        st = os.stat(target)
    except FileNotFoundError:
        st = None
    except OSError as e:
        raise OutputError(f"cannot write {path}: {e.strerror}") from None
    if st is not None:
        if not stat.S_ISREG(st.st_mode):
            raise OutputError(f"cannot write {path}: it is {_describe(st.st_mode)}")
        if not os.access(target, os.W_OK):
            raise OutputError(f"cannot write {path}: permission denied")
    _check_parent(target.parent, path)
    return path


def check_output_dir(path, what: str = "output folder") -> Path:
    """Refuse, before any work, an output folder that cannot be made or written; returns the path."""
    if path is None or str(path).strip() == "":
        raise OutputError(f"the {what} path is empty")
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"cannot use {path} as the {what}: it is a file, not a folder")
    if path.exists():
        if not os.access(path, os.W_OK | os.X_OK):
            raise OutputError(f"cannot write into {path}: permission denied")
        return path
    _check_parent(path.parent, path)
    return path


def make_dir(path) -> Path:
    """check_output_dir, then create it (and its parents)."""
    path = check_output_dir(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(f"cannot create {path}: {e.strerror}") from None
    return path


def reclaim_temporaries(folder, name: str | None = None) -> int:
    """Remove the temporaries (`.NAME.PID.N.tmp`) in `folder` whose writing process is dead; `name` limits it to
    one target. Returns how many were removed."""
    n = 0
    try:
        entries = os.listdir(folder)
    except OSError:
        return 0
    for entry in entries:
        m = _TMP.match(entry)
        if m is None or (name is not None and m["name"] != name):
            continue
        pid = int(m["pid"])
        if pid != os.getpid() and not pid_alive(pid):
            try:
                os.unlink(os.path.join(folder, entry))
                n += 1
            except OSError:
                pass
    return n


_counter = iter(range(1 << 62))


def temporary_for(path) -> Path:
    """A hidden name beside `path` that no other writer uses: `.NAME.PID.N.tmp`."""
    path = Path(path)
    return path.parent / f".{path.name}.{os.getpid()}.{next(_counter)}.tmp"


def atomic_write(path, data) -> None:
    """Replace the file at `path` (or the regular file its symbolic link points to) by `data` (bytes, or a
    function that writes into a binary file object), through a temporary file renamed into place."""
    target = resolve_target(path)
    try:
        st = os.stat(target)
        if not stat.S_ISREG(st.st_mode):
            raise OutputError(f"cannot write {path}: it is {_describe(st.st_mode)}")
    except FileNotFoundError:
        pass
    target.parent.mkdir(parents=True, exist_ok=True)
    reclaim_temporaries(target.parent, target.name)
    tmp = temporary_for(target)
    try:
        with open(tmp, "xb") as f:
            if callable(data):
                data(f)
            else:
                f.write(data)
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
