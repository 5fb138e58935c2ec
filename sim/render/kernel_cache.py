"""numba keeps a function's compiled code while the function's own file is unchanged, even when a function of another
file that it calls has changed: a group of kernel files' cached code is dropped together when any file of the group
has changed since it was compiled (a source tree being edited; an installed one never changes)."""
from __future__ import annotations

import hashlib
from pathlib import Path


def drop_stale(folder: Path, files: tuple[str, ...], cached: str, mark_name: str) -> None:
    """Remove the cache entries `cached` (a glob of numba's index and data files' stem, e.g. `raster_*`) under
    folder/__pycache__ unless `files` are byte for byte what they were when the mark `mark_name` was written."""
    stamp = hashlib.sha1(b"".join((folder / f).read_bytes() for f in files)).hexdigest()
    cache = folder / "__pycache__"
    mark = cache / mark_name
    if mark.is_file() and mark.read_text() == stamp:
        return
    try:
        for f in cache.glob(f"{cached}.nb[ic]"):
            f.unlink(missing_ok=True)
        cache.mkdir(exist_ok=True)
        mark.write_text(stamp)
    except OSError:   # a folder this process cannot write: numba caches elsewhere, or not at all
        pass
