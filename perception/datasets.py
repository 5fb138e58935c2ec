"""PyTorch readers of the dataset format (perception/shards.py).

FrameDataset: map-style, random access (`dataset[i]`), for evaluation and small sets.
FrameStream: iterable, reads whole row groups in a shuffled shard order through a shuffle buffer, split
across DataLoader workers: the way to train on hundreds of thousands of frames.

Both yield (image, target): image a uint8 tensor (3, H, W) RGB, target a float32 tensor of the requested
labels normalised with DeepDriving's affine maps (shm_bridge.vocabulary.normalise), or raw with
normalised=False.
"""
from __future__ import annotations

import bisect
import math
from pathlib import Path

import numpy as np
import torch

from shm_bridge.vocabulary import PAPER_INDICATORS, normalise

from .shards import SCHEMA, Dataset, DatasetError, ShardReader, decode_image


def _check_labels(labels) -> tuple[str, ...]:
    labels = tuple(labels)
    missing = [n for n in labels if n not in SCHEMA.names or n == "image"]
    if missing:
        raise DatasetError(f"the dataset has no labels {missing}")
    return labels


def _image_tensor(rgb: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(rgb.transpose(2, 0, 1)))


def _target(values: np.ndarray, labels: tuple[str, ...], normalised: bool) -> torch.Tensor:
    values = np.asarray(values, dtype=np.float32)
    return torch.from_numpy(normalise(values, labels) if normalised else values)


class FrameDataset(torch.utils.data.Dataset):
    def __init__(self, root: str | Path, split: str | None = "train", labels=PAPER_INDICATORS,
                 normalised: bool = True):
        self.data = Dataset(Path(root))
        self.labels = _check_labels(labels)
        self.normalised = normalised
        self.shards = self.data.select(split)
        if not self.shards:
            raise DatasetError(f"dataset {self.data.root} has no frames in split '{split}'")
        self._starts = np.cumsum([0] + [s.frames for s in self.shards]).tolist()
        self._readers: dict[int, ShardReader] = {}  # opened lazily, per worker process

    def __len__(self) -> int:
        return self._starts[-1]

    def _locate(self, i: int) -> tuple[int, int]:
        if not 0 <= i < len(self):
            raise IndexError(i)
        k = bisect.bisect_right(self._starts, i) - 1
        return k, i - self._starts[k]

    def record(self, i: int) -> tuple[np.ndarray, dict]:
        """Frame i as (RGB image, every label column)."""
        k, row = self._locate(i)
        if k not in self._readers:
            self._readers[k] = self.data.reader(self.shards[k])
        return self._readers[k].row(row)

    def __getitem__(self, i: int):
        image, record = self.record(int(i))
        return _image_tensor(image), _target([record[n] for n in self.labels], self.labels, self.normalised)

    def __getstate__(self):  # DataLoader workers reopen the shards themselves
        state = dict(self.__dict__)
        state["_readers"] = {}
        return state


class FrameStream(torch.utils.data.IterableDataset):
    def __init__(self, root: str | Path, split: str | None = "train", labels=PAPER_INDICATORS,
                 normalised: bool = True, shuffle: bool = True, seed: int = 0, buffer: int = 2048):
        self.data = Dataset(Path(root))
        self.labels = _check_labels(labels)
        self.normalised, self.shuffle, self.seed, self.buffer = normalised, shuffle, seed, buffer
        self.shards = self.data.select(split)
        if not self.shards:
            raise DatasetError(f"dataset {self.data.root} has no frames in split '{split}'")
        self.epoch = 0

    def __len__(self) -> int:
        return sum(s.frames for s in self.shards)

    def set_epoch(self, epoch: int) -> None:
        """A new shuffle order per epoch (call before iterating, as with DistributedSampler)."""
        self.epoch = epoch

    def _my_shards(self):
        order = list(range(len(self.shards)))
        rng = np.random.default_rng([self.seed, self.epoch])
        if self.shuffle:
            rng.shuffle(order)
        info = torch.utils.data.get_worker_info()
        if info is not None:
            order = order[info.id::info.num_workers]
        return order, rng

    def __iter__(self):
        order, rng = self._my_shards()
        pool: list = []
        columns = ["image", *self.labels]
        for k in order:
            reader = self.data.reader(self.shards[k])
            for table in reader.iter_row_groups():
                table = table.select(columns)
                images = table.column("image").to_pylist()
                values = np.stack([table.column(n).to_numpy(zero_copy_only=False).astype(np.float32)
                                   for n in self.labels], axis=1)
                for img, v in zip(images, values):
                    pool.append((img, v))
                if not self.shuffle:
                    yield from self._emit(pool)
                    pool = []
                elif len(pool) >= self.buffer:
                    rng.shuffle(pool)
                    keep = math.ceil(self.buffer / 2)  # emit half, keep half to mix with the next shards
                    yield from self._emit(pool[keep:])
                    pool = pool[:keep]
        if self.shuffle:
            rng.shuffle(pool)
        yield from self._emit(pool)

    def _emit(self, items):
        for img, v in items:
            yield _image_tensor(decode_image(img)), _target(v, self.labels, self.normalised)
