"""Decoded frames kept on disk, so that training decodes each stored image once instead of once per epoch.

For every shard of a dataset and every camera, `FrameCache.prepare` writes the shard's images decoded, as one
uint8 array (steps, height, width, 3) in NumPy's .npy format, into the cache folder (default `DATA/.frames/`);
readers map it into memory (`np.load(mmap_mode="r")`), so the operating system's page cache shares it between the
training process and its loader workers, and a dataset larger than memory still works. A cached image is the
decoded stored image, bit for bit (the stored formats decode deterministically), so training reads exactly the
samples it read before, only faster.

A cache file is named after its shard's SHA-256 (from the manifest): a shard that was regenerated gets a new file;
files that no shard names any more are removed by `prepare`. Files are written through a temporary name and
renamed into place: a killed run leaves no half-written cache behind (the next `prepare` reclaims its temporary).
"""
from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from core.files import OutputError, make_dir, reclaim_temporaries, temporary_for
from perception.shards import Dataset, DatasetError, ShardInfo, decode_image, image_column

FOLDER = ".frames"


class FrameCache:
    """The decoded frames of one dataset: `frames(shard, camera)` -> (steps, h, w, 3) uint8, memory-mapped."""

    def __init__(self, data: Dataset, folder: Path | None = None):
        self.data = data
        self.folder = Path(folder) if folder is not None else data.root / FOLDER
        self.cameras = tuple(c.name for c in data.declaration.cameras)
        self._open: dict[tuple[str, str], np.ndarray] = {}

    def path(self, shard: ShardInfo, camera: str) -> Path:
        if not shard.sha256:
            raise DatasetError(f"shard {shard.file} of {self.data.root} has no SHA-256 in the manifest; it cannot "
                               "be cached")
        return self.folder / f"{Path(shard.file).stem}.{camera}.{shard.sha256[:16]}.npy"

    def missing(self, shards: list[ShardInfo]) -> list[ShardInfo]:
        return [s for s in shards if any(not self.path(s, c).is_file() for c in self.cameras)]

    def prepare(self, shards: list[ShardInfo] | None = None, progress=None) -> int:
        """Decode the shards (default: all) that are not cached yet; returns how many were decoded. Bytes needed
        are checked against the free space first."""
        shards = self.data.shards if shards is None else shards
        todo = self.missing(shards)
        make_dir(self.folder)
        reclaim_temporaries(self.folder)
        self._remove_stale()
        if not todo:
            return 0
        need = sum(s.frames * cam.size for s in todo for cam in self.data.declaration.cameras)
        free = shutil.disk_usage(self.folder).free
        if need > free - (256 << 20):
            raise OutputError(f"the decoded frames of {len(todo)} shards need {need / 2**30:.1f} GiB in "
                              f"{self.folder}, which has {free / 2**30:.1f} GiB free (train with --no-cache)")
        for shard in todo:
            self._write(shard)
            if progress is not None:
                progress(shard.frames)
        return len(todo)

    def _write(self, shard: ShardInfo) -> None:
        reader = self.data.reader(shard)
        for cam in self.data.declaration.cameras:
            target = self.path(shard, cam.name)
            tmp = temporary_for(target)
            column = image_column(cam.name)
            try:
                out = np.lib.format.open_memmap(tmp, mode="w+", dtype=np.uint8,
                                                shape=(shard.frames, cam.height, cam.width, cam.channels))
                step = 0
                for group in reader.iter_row_groups((column,)):
                    for data in group.column(column).to_pylist():
                        out[step] = decode_image(data)
                        step += 1
                if step != shard.frames:
                    raise DatasetError(f"shard {shard.file} has {step} steps, the manifest says {shard.frames}")
                out.flush()
                del out
                os.replace(tmp, target)
            finally:
                tmp.unlink(missing_ok=True)

    def _remove_stale(self) -> None:
        keep = {self.path(s, c).name for s in self.data.shards if s.sha256 for c in self.cameras}
        for p in self.folder.glob("*.npy"):
            if p.name not in keep:
                p.unlink(missing_ok=True)

    def frames(self, shard: ShardInfo, camera: str) -> np.ndarray:
        key = (shard.file, camera)
        if key not in self._open:
            path = self.path(shard, camera)
            try:
                self._open[key] = np.load(path, mmap_mode="r")
            except (OSError, ValueError) as e:
                raise DatasetError(f"the frame cache {path} cannot be read ({e}); remove {self.folder} to rebuild "
                                   "it") from None
        return self._open[key]

    def __getstate__(self):   # DataLoader workers map the files themselves
        state = dict(self.__dict__)
        state["_open"] = {}
        return state


def prepare_cache(data: Dataset, shards: list[ShardInfo], folder: Path | None = None, log=print) -> FrameCache:
    """The dataset's frame cache with `shards` decoded, with a progress bar when there is work."""
    cache = FrameCache(data, folder)
    todo = cache.missing(shards)
    if todo:
        log(f"decoding {sum(s.frames for s in todo)} frames once into {cache.folder} (the frame cache)")
        with tqdm(total=sum(s.frames for s in todo), unit="frame", desc="frame cache", file=sys.stderr,
                  dynamic_ncols=True, mininterval=1.0 if sys.stderr.isatty() else 30.0) as bar:
            cache.prepare(shards, bar.update)
    else:
        cache.prepare(shards)
    return cache
