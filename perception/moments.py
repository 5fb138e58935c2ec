"""MultiNet's data moments: every moment of one or more datasets of a world with behavioural modes, its images at
the network's input size from the frame cache (perception/frame_cache.py).

Z2Color reads 94 x 168 images; the sidewalk records 188 x 336 PNGs. Decoding two PNGs and averaging them 2x2 costs
about a millisecond a step, and a study passes over every moment 10-24 times in each of several trainings, so each
shard's images are decoded and downsampled once into the dataset's frame cache at that size
(`<dataset>/.frames/94x168/`) and mapped from there: the operating system keeps them in memory once for every
process that reads them, and no image is decoded again. A dataset folder that cannot be written is read into memory
instead (every training then decodes it again; a line says so).

`Moments` indexes every data moment; `batch(ids)` assembles them as the network reads them.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import torch

from core.files import OutputError
from perception.datasets import SampleSpec
from perception.frame_cache import FOLDER, FrameCache
from perception.shards import Dataset, DatasetError, ShardInfo

VALIDATION_SHARE = 0.10


def shard_images(cache: FrameCache, shard: ShardInfo) -> list[np.ndarray]:
    """The shard's images from the cache, one (steps, h, w, 3) array per camera in declaration order."""
    return [cache.frames(shard, camera) for camera in cache.cameras]


def cached(ds: Dataset, size: tuple[int, int], log=print) -> FrameCache:
    """The dataset's frame cache at `size` with every shard decoded (held in memory where it cannot be written)."""
    cache = FrameCache(ds, size=size)
    try:
        cache.prepare()
    except (OSError, OutputError, DatasetError) as e:
        log(f"cannot cache the moments of {ds.root} ({getattr(e, 'strerror', None) or e}): reading them into memory")
        cache.hold(ds.shards)
    return cache


class Moments:
    """Every data moment of some datasets of one world with behavioural modes, images at `size` (from the cache).

    A moment is an index: its step's images are not copied. Moments whose targets include a step that a network
    drove (the sidewalk's operation 1, recorded during autonomy runs) are left out: a network's own command is no
    label. The expert's corrections stay in (the MultiNet paper's DAgger variant)."""

    def __init__(self, roots, size: tuple[int, int], targets=None, log=print):
        datasets = [Dataset(Path(r)) for r in roots]
        decl = datasets[0].declaration
        for ds in datasets[1:]:
            if ds.world != decl.name:
                raise DatasetError(f"{ds.root} is a {ds.world} dataset, not a {decl.name} one: datasets trained "
                                   "together must be of one world")
        if not decl.modes:
            raise DatasetError(f"the {decl.name} world has no behavioural modes: train another model family")
        self.decl, self.size = decl, size
        self.roots = [str(ds.root) for ds in datasets]
        self.renderers = {r for ds in datasets for r in ds.renderers}
        self.spec = SampleSpec(decl, targets, normalised=False)
        self.instants = np.asarray(self.spec.moment.instants)
        self.cameras = len(decl.cameras)
        self.arrays: list[list[np.ndarray]] = []    # one per shard: one (steps, h, w, 3) array per camera
        starts: list[int] = []
        modes: list[int] = []
        targets_: list[np.ndarray] = []
        self.episodes: list[tuple[str, int]] = []
        self.offsets = [0]                            # first global step of every shard, and the total
        t0 = time.perf_counter()
        for ds in datasets:
            cache = cached(ds, size, log)
            for shard in ds.shards:
                for t, mode, target in self._shard_moments(ds, shard):
                    starts.append(self.offsets[-1] + t)
                    modes.append(mode)
                    targets_.append(target)
                    self.episodes.append((str(ds.root), shard.episode))
                self.arrays.append(shard_images(cache, shard))
                self.offsets.append(self.offsets[-1] + shard.frames)
        if not starts:
            raise DatasetError("the datasets hold no complete data moment")
        self.index = np.asarray(starts)
        self.modes = np.asarray(modes, dtype=np.int64)
        self.targets = np.asarray(targets_, dtype=np.float32)
        self._offsets = np.asarray(self.offsets)
        mb = self.offsets[-1] * self.cameras * size[0] * size[1] * 3 / 1e6
        log(f"{len(self.index)} data moments of {len(datasets)} dataset(s) ({mb:.0f} MB of images at "
            f"{size[1]}x{size[0]}, cached in {FOLDER}/ beside each dataset) ready in "
            f"{time.perf_counter() - t0:.0f} s")

    def _shard_moments(self, ds: Dataset, shard: ShardInfo):
        """(step, mode, raw targets) of every moment of one shard whose targets the expert drove."""
        reader = ds.reader(shard)
        table = reader.labels(self.spec.columns)
        values = np.stack([table.column(n).to_numpy(zero_copy_only=False).astype(np.float64)
                           for n in self.spec.targets], axis=1)
        mode = table.column(self.decl.mode_field).to_numpy().astype(np.int64)
        by_expert = np.ones(len(values), dtype=bool)
        if "operation" in self.decl.truth_names:   # 1: autonomous, a network's command, never a label
            by_expert = reader.labels(["operation"]).column("operation").to_numpy() != 1
        horizon = self.spec.moment.horizon
        for t in self.spec.starts(len(values)):
            if by_expert[t + 1:t + 1 + horizon].all():
                yield t, int(mode[t]), self.spec.target_values(values, t)

    def __len__(self) -> int:
        return len(self.index)

    def _sources(self, ids):
        """(sample, instant, camera, its (h, w, 3) image) of every image of the moments `ids`."""
        steps = self.index[np.asarray(ids)][:, None] + self.instants[None, :]        # (B, instants)
        shard = np.searchsorted(self._offsets, steps, side="right") - 1
        for b, i in np.ndindex(*steps.shape):
            k = int(shard[b, i])
            step = int(steps[b, i]) - self.offsets[k]
            for c, camera in enumerate(self.arrays[k]):
                yield b, i, c, camera[step]

    def images(self, ids) -> np.ndarray:
        """uint8 (B, h, w, instants * cameras * 3): the moments' images, channels oldest instant first, cameras in
        declaration order, RGB (the channel order of perception/datasets.py), channels last in memory."""
        # the cached images are copied whole first, then interleaved in one reordering copy that moves whole pixels
        # (3-byte elements): 45 % faster than writing each image into its interleaved place byte by byte
        h, w = self.size
        out = np.empty((len(ids), len(self.instants), self.cameras, h, w, 3), dtype=np.uint8)
        for b, i, c, image in self._sources(ids):
            out[b, i, c] = image
        pixels = out.view(np.dtype("V3"))[..., 0]                                  # (B, instants, cameras, h, w)
        return np.ascontiguousarray(pixels.transpose(0, 3, 4, 1, 2)).view(np.uint8).reshape(len(ids), h, w, -1)

    def looked_up(self, ids, table: np.ndarray) -> np.ndarray:
        """table[images(ids)], of table's type (a network's 256 scaled values: Regressor.pixel_table), written as
        the images are gathered: one pass instead of images' two and the lookup's one."""
        from perception.input_kernels import place_looked_up  # numba: only where moments are trained on
        h, w = self.size
        out = np.empty((len(ids), h, w, len(self.instants) * self.cameras * 3), dtype=table.dtype)
        for b, i, c, image in self._sources(ids):
            place_looked_up(image, table, out[b], 3 * (i * self.cameras + c))
        return out

    def batch(self, ids) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(uint8 images (B, instants * cameras * 3, h, w) in channels-last memory, modes (B,), raw targets)."""
        ids = np.asarray(ids)
        return (torch.from_numpy(self.images(ids)).permute(0, 3, 1, 2), *self.labels(ids))

    def labels(self, ids) -> tuple[torch.Tensor, torch.Tensor]:
        """(modes (B,), raw targets (B, targets)) of the moments."""
        ids = np.asarray(ids)
        return torch.from_numpy(self.modes[ids]), torch.from_numpy(self.targets[ids])

    def split(self, modes: list[int], seed: int = 0) -> tuple[dict[int, np.ndarray], np.ndarray]:
        """({mode: training moment ids}, held-out ids): 10 % of each mode's episodes of the first dataset (at least
        one) held out whole, and the held-out moments subsampled so that every mode has as many. The datasets after
        the first (corrections merged in, DAgger rounds) are training data only, so a network retrained with them
        is validated on the same moments as before."""
        rng = np.random.default_rng([seed, 0x5A1])
        train, held = {}, {}
        for m in modes:
            ids = np.flatnonzero(self.modes == m)
            if not len(ids):
                raise DatasetError(f"the data hold no moment of mode {self.decl.modes[m]}")
            eps = sorted({self.episodes[i] for i in ids if self.episodes[i][0] == self.roots[0]})
            if len(eps) < 2:
                raise DatasetError(f"mode {self.decl.modes[m]} has {len(eps)} episode(s) in {self.roots[0]}: at "
                                   "least 2 are needed to hold one out for validation")
            k = max(1, int(round(VALIDATION_SHARE * len(eps))))
            out = {eps[j] for j in rng.choice(len(eps), k, replace=False)}
            is_held = np.array([self.episodes[i] in out for i in ids])
            train[m], held[m] = ids[~is_held], ids[is_held]
        n = min(len(v) for v in held.values())
        held_ids = np.concatenate([np.sort(rng.choice(v, n, replace=False)) for v in held.values()])
        return train, held_ids
