"""The sumo processes a process started, read from the process table (/proc), for tests that nothing is left."""
import os
from pathlib import Path


def sumo_children(parent: int | None = None) -> list[int]:
    """Live `sumo` processes whose parent is `parent` (default: this process)."""
    parent = os.getpid() if parent is None else parent
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:   # ended while we looked
            continue
        name = text[text.index("(") + 1:text.rindex(")")]
        state, ppid = text[text.rindex(")") + 2:].split()[:2]
        if name == "sumo" and int(ppid) == parent and state != "Z":
            found.append(int(stat.parent.name))
    return found
