"""Decoded frames kept on disk, so that training decodes each stored image once instead of once per epoch: the one
frame cache of both trainers (the SGD trainer's frame stream, perception/datasets.py; MultiNet's data moments,
perception/moments.py).

For every shard of a dataset and every camera, `FrameCache.prepare` writes the shard's images decoded, as one
uint8 array (steps, height, width, channels) in NumPy's .npy format, into the cache folder:

    <dataset>/.frames/<shard stem>.<camera>.<first 16 hex digits of the shard's SHA-256>.npy          stored size
    <dataset>/.frames/<h>x<w>/<shard stem>.<camera>.<first 16 hex digits of the shard's SHA-256>.npy   size=(h, w)

At the stored size a cached image is the decoded stored image, bit for bit (the stored formats decode
deterministically), so training reads exactly the samples it read before, only faster. With a `size` (Z2Color
reads 94 x 168 images of the sidewalk's 188 x 336), each image is resampled once by OpenCV's area resampling,
which for the factor of two is the 2x2 mean rounded to a whole grey level: within half a grey level of the float
mean Z2Color's own input scaling takes of full-size frames (perception/models.py).

Readers map the files into memory (`np.load(mmap_mode="r")`), so the operating system's page cache shares them
between the training process and its loader workers, and a dataset larger than memory still works. A file is named
after its shard's SHA-256 (from the manifest): a shard that was regenerated gets a new file; files that no shard
names any more are removed by `prepare`, and a file that cannot be read or has the wrong shape is written again.
Files are written through a temporary name and renamed into place: a killed run leaves no half-written cache
behind (the next `prepare` reclaims its temporary). A cache whose folder cannot be written can `hold` the frames in
memory instead.
"""
from __future__ import annotations

import os
import shutil
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from core.files import OutputError, make_dir, reclaim_temporaries, temporary_for
from perception.shards import Dataset, DatasetError, ShardInfo, decode_image, image_column

FOLDER = ".frames"
DECODERS = 2   # threads decoding a shard's images (OpenCV releases the interpreter while it decodes and resamples)


def to_size(rgb: np.ndarray, size: tuple[int, int] | None) -> np.ndarray:
    """An (H, W, 3) uint8 image at (h, w) = size by area resampling (unchanged when it is that size already or
    size is None)."""
    if size is None or rgb.shape[:2] == tuple(size):
        return rgb
    h, w = size
    return cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA)


class FrameCache:
    """The decoded frames of one dataset at one size (None: as stored): `frames(shard, camera)` -> (steps, h, w,
    channels) uint8, memory-mapped."""

    def __init__(self, data: Dataset, folder: Path | None = None, size: tuple[int, int] | None = None):
        self.data = data
        self.size = None if size is None else (int(size[0]), int(size[1]))
        root = Path(folder) if folder is not None else data.root / FOLDER
        self.folder = root if self.size is None else root / f"{self.size[0]}x{self.size[1]}"
        self.cameras = tuple(c.name for c in data.declaration.cameras)
        self._open: dict[tuple[str, str], np.ndarray] = {}

    def path(self, shard: ShardInfo, camera: str) -> Path:
        if not shard.sha256:
            raise DatasetError(f"shard {shard.file} of {self.data.root} has no SHA-256 in the manifest; it cannot "
                               "be cached")
        return self.folder / f"{Path(shard.file).stem}.{camera}.{shard.sha256[:16]}.npy"

    def shape(self, shard: ShardInfo, camera: str) -> tuple[int, int, int, int]:
        """The cached array's shape: (steps, h, w, channels)."""
        cam = next(c for c in self.data.declaration.cameras if c.name == camera)
        h, w = self.size if self.size is not None else (cam.height, cam.width)
        return shard.frames, h, w, cam.channels

    def _usable(self, shard: ShardInfo, camera: str) -> bool:
        path = self.path(shard, camera)
        if not path.is_file():
            return False
        try:
            return np.load(path, mmap_mode="r").shape == self.shape(shard, camera)
        except (OSError, ValueError):
            return False   # a damaged file: written again

    def missing(self, shards: list[ShardInfo]) -> list[ShardInfo]:
        return [s for s in shards if any(not self._usable(s, c) for c in self.cameras)]

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
        need = sum(int(np.prod(self.shape(s, c))) for s in todo for c in self.cameras)
        free = shutil.disk_usage(self.folder).free
        if need > free - (256 << 20):
            raise OutputError(f"the decoded frames of {len(todo)} shards need {need / 2**30:.1f} GiB in "
                              f"{self.folder}, which has {free / 2**30:.1f} GiB free (train with --set cache=false)")
        for shard in todo:
            self._write(shard)
            if progress is not None:
                progress(shard.frames)
        return len(todo)

    def decode(self, shard: ShardInfo, out: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """Every step's images of one shard at the cache's size, by camera: {camera: (steps, h, w, channels)}, into
        `out` where given (arrays of that shape), else into memory."""
        if out is None:
            out = {c: np.empty(self.shape(shard, c), dtype=np.uint8) for c in self.cameras}
        columns = [image_column(c) for c in self.cameras]
        step = 0

        def one(job) -> None:
            t, camera, data = job
            out[camera][t] = to_size(decode_image(data), self.size)

        with ThreadPoolExecutor(DECODERS) as pool:
            for group in self.data.reader(shard).iter_row_groups(columns):
                rows = list(zip(*(group.column(c).to_pylist() for c in columns)))
                if step + len(rows) > shard.frames:
                    raise DatasetError(f"shard {shard.file} has more steps than the manifest's {shard.frames}")
                list(pool.map(one, [(step + t, camera, data) for t, row in enumerate(rows)
                                    for camera, data in zip(self.cameras, row)]))
                step += len(rows)
        if step != shard.frames:
            raise DatasetError(f"shard {shard.file} has {step} steps, the manifest says {shard.frames}")
        return out

    def _write(self, shard: ShardInfo) -> None:
        targets = {c: self.path(shard, c) for c in self.cameras}
        tmps = {c: temporary_for(p) for c, p in targets.items()}
        try:
            maps = {c: np.lib.format.open_memmap(tmps[c], mode="w+", dtype=np.uint8, shape=self.shape(shard, c))
                    for c in self.cameras}
            self.decode(shard, dict[str, np.ndarray](maps))
            for array in maps.values():
                array.flush()
            del maps, array
            for c, target in targets.items():
                os.replace(tmps[c], target)
        finally:
            for tmp in tmps.values():
                tmp.unlink(missing_ok=True)

    def _remove_stale(self) -> None:
        keep = {self.path(s, c).name for s in self.data.shards if s.sha256 for c in self.cameras}
        for p in self.folder.glob("*.npy"):
            if p.name not in keep:
                p.unlink(missing_ok=True)

    def hold(self, shards: list[ShardInfo]) -> None:
        """Decode the shards that are not cached into memory, where `frames` finds them (for a cache folder that
        cannot be written: every run decodes them again)."""
        for shard in shards:
            if shard.sha256 and not self.missing([shard]):
                continue
            for camera, array in self.decode(shard).items():
                self._open[(shard.file, camera)] = array

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

    def __getstate__(self):   # DataLoader workers map the files themselves; frames held in memory travel along
        state = dict(self.__dict__)
        state["_open"] = {k: v for k, v in self._open.items() if not isinstance(v, np.memmap)}
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
