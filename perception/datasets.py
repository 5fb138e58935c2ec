"""PyTorch readers of the dataset format (perception/shards.py), for any declared world.

A sample is assembled from the recorded steps of one episode as the world's declaration says (its `moment`):
the images of the steps at the moment's instants (the highway: the current step; MultiNet's data moment: the
stereo pair now and one step, 33 ms, earlier), and the targets: the labels of the current step (horizon 0) or of
the `horizon` following steps (MultiNet: the next 10 steering and 10 motor values). Every step that has the steps
it needs starts one sample; nothing is stored twice.

FrameDataset: map-style, random access (`dataset[i]`), for evaluation, balanced sampling and small sets.
FrameStream: iterable, reads whole episodes in a shuffled order through a shuffle buffer, split across DataLoader
workers (and across the ranks of a distributed run): the way to train on hundreds of thousands of samples.

Both yield (images, mode, target): images a uint8 tensor (C, H, W) with C = instants x cameras x 3 (oldest instant
first, cameras in declaration order, RGB), mode an int64 scalar tensor (the behavioural mode index, -1 for a world
without modes), target a float32 tensor of the outputs (normalised with the declaration's affine maps, or raw
with normalised=False).
"""
from __future__ import annotations

import bisect
import math
from collections import OrderedDict
from pathlib import Path

import numpy as np
import torch

from core import worlds
from core.declaration import Moment, WorldDeclaration, base_name, expand
from perception.frame_cache import FrameCache
from perception.shards import Dataset, DatasetError, ShardReader, decode_image, image_column


class SampleSpec:
    """What one sample of a dataset holds: which targets over which horizon, which images at which instants."""

    def __init__(self, decl: WorldDeclaration, targets=None, moment: Moment | None = None, normalised: bool = True):
        self.decl = decl
        self.targets = tuple(decl.targets if targets is None else targets)
        self.moment = decl.moment if moment is None else moment
        self.normalised = normalised
        labels = set(decl.label_names)
        missing = [n for n in self.targets if n not in labels]
        if missing:
            raise DatasetError(f"the {decl.name} dataset has no labels {missing} (labels: "
                               f"{', '.join(decl.label_names)})")
        if not self.targets:
            raise DatasetError("no targets to learn")
        self.outputs = expand(self.targets, self.moment.horizon)
        self.mode_field = decl.mode_field
        self.columns = tuple(dict.fromkeys(self.targets + ((decl.mode_field,) if decl.mode_field else ())))
        self.images = tuple(image_column(c.name) for c in decl.cameras)

    @property
    def channels(self) -> int:
        return len(self.moment.instants) * sum(c.channels for c in self.decl.cameras)

    def starts(self, steps: int) -> range:
        """The steps of an episode of `steps` steps that start a sample."""
        return range(-self.moment.earliest, steps - self.moment.horizon)

    def target_values(self, values: np.ndarray, t: int) -> np.ndarray:
        """The raw target vector of the sample at step t, from the episode's (steps, targets) label array."""
        h = self.moment.horizon
        if h == 0:
            return values[t]
        return values[t + 1:t + 1 + h].T.reshape(-1)   # each target's h future values, target by target

    def target_tensor(self, raw: np.ndarray) -> torch.Tensor:
        raw = np.asarray(raw, dtype=np.float32)
        return torch.from_numpy(self.decl.normalise(raw, self.outputs) if self.normalised else raw)


def _stack(images, channels_last: bool = False) -> torch.Tensor:
    """(h, w, 3) RGB arrays -> one uint8 (3 * len, h, w) tensor; channels_last: its channels innermost in memory,
    as they are in the frames (a batch of them is channels-last already: no transposing copy here or in training)."""
    if not channels_last:
        hwc = np.concatenate(images, axis=2) if len(images) > 1 else images[0]
        return torch.from_numpy(np.ascontiguousarray(hwc.transpose(2, 0, 1)))
    if len(images) == 1:
        hwc = np.array(images[0])   # the cache's is read-only
    elif all(image.dtype == np.uint8 and image.shape == images[0].shape for image in images):
        from perception.input_kernels import interleave  # numba: only once samples are stacked
        hwc = interleave(images)
    else:
        hwc = np.concatenate(images, axis=2)
    return torch.from_numpy(hwc).permute(2, 0, 1)


def collate_channels_last(batch: list) -> tuple:
    """default_collate for a FrameStream with channels_last: its images stacked as they lie in memory, which makes
    a channels-last batch without the transposing copies of stacking them as (C, h, w) and converting back."""
    images = torch.stack([sample[0].permute(1, 2, 0) for sample in batch]).permute(0, 3, 1, 2)
    return (images, *torch.utils.data.default_collate([sample[1:] for sample in batch]))


def _mode_tensor(value) -> torch.Tensor:
    return torch.tensor(-1 if value is None else int(value), dtype=torch.int64)


class FrameDataset(torch.utils.data.Dataset):
    def __init__(self, root: str | Path, split: str | None = "train", targets=None, normalised: bool = True,
                 moment: Moment | None = None):
        self.data = Dataset(Path(root))
        self.spec = SampleSpec(self.data.declaration, targets, moment, normalised)
        self.shards = self.data.select(split)
        self._starts_of = [self.spec.starts(s.frames) for s in self.shards]
        if not self.shards or not sum(len(r) for r in self._starts_of):
            raise DatasetError(f"dataset {self.data.root} has no samples in split '{split}'")
        self._offsets = np.cumsum([0] + [len(r) for r in self._starts_of]).tolist()
        self._readers: dict[int, ShardReader] = {}    # opened lazily, per worker process
        self._values: dict[int, tuple[np.ndarray, np.ndarray | None]] = {}
        self._groups: OrderedDict = OrderedDict()     # (shard, row group) -> table, a few kept

    @property
    def targets(self) -> tuple[str, ...]:
        return self.spec.targets

    @property
    def outputs(self) -> tuple[str, ...]:
        return self.spec.outputs

    def __len__(self) -> int:
        return self._offsets[-1]

    def locate(self, i: int) -> tuple[int, int]:
        """(shard index, step) of sample i."""
        if not 0 <= i < len(self):
            raise IndexError(i)
        k = bisect.bisect_right(self._offsets, i) - 1
        return k, self._starts_of[k][i - self._offsets[k]]

    def _reader(self, k: int) -> ShardReader:
        if k not in self._readers:
            self._readers[k] = self.data.reader(self.shards[k])
        return self._readers[k]

    def _episode_values(self, k: int) -> tuple[np.ndarray, np.ndarray | None]:
        """(steps, targets) raw label array and the mode per step of shard k."""
        if k not in self._values:
            table = self._reader(k).labels(self.spec.columns)
            values = np.stack([table.column(n).to_numpy(zero_copy_only=False).astype(np.float64)
                               for n in self.spec.targets], axis=1)
            modes = table.column(self.spec.mode_field).to_numpy() if self.spec.mode_field else None
            self._values[k] = (values, modes)
        return self._values[k]

    def _image_bytes(self, k: int, step: int) -> list[bytes]:
        reader = self._reader(k)
        starts = reader._starts
        g = int(np.searchsorted(starts, step, side="right") - 1)
        key = (k, g)
        table = self._groups.get(key)
        if table is None:
            table = reader.row_group(g, self.spec.images)
            self._groups[key] = table
            if len(self._groups) > 4:
                self._groups.popitem(last=False)
        row = step - int(starts[g])
        return [table.column(c)[row].as_py() for c in self.spec.images]

    def images(self, k: int, t: int) -> list[np.ndarray]:
        """The decoded images of the sample at step t of shard k, oldest instant first, cameras in order."""
        out: list[np.ndarray] = []
        for dt in self.spec.moment.instants:
            out.extend(decode_image(b) for b in self._image_bytes(k, t + dt))
        return out

    def mode_of(self, i: int) -> int:
        k, t = self.locate(i)
        modes = self._episode_values(k)[1]
        return -1 if modes is None else int(modes[t])

    def modes(self) -> np.ndarray:
        """The behavioural mode index of every sample (-1 without modes); reads labels only."""
        out = []
        for k, starts in enumerate(self._starts_of):
            modes = self._episode_values(k)[1]
            out.append(np.full(len(starts), -1) if modes is None else np.asarray(modes)[list(starts)])
        return np.concatenate(out).astype(np.int64) if out else np.zeros(0, np.int64)

    def raw_targets(self, i: int) -> np.ndarray:
        k, t = self.locate(i)
        return self.spec.target_values(self._episode_values(k)[0], t)

    def record(self, i: int) -> tuple[tuple, dict]:
        """Sample i's current step as stored: (images per camera, every other column)."""
        k, t = self.locate(i)
        return self._reader(k).row(t)

    def __getitem__(self, i: int):
        k, t = self.locate(int(i))
        values, modes = self._episode_values(k)
        return (_stack(self.images(k, t)), _mode_tensor(None if modes is None else modes[t]),
                self.spec.target_tensor(self.spec.target_values(values, t)))

    def __getstate__(self):  # DataLoader workers reopen the shards themselves
        state = dict(self.__dict__)
        state["_readers"], state["_groups"] = {}, OrderedDict()
        return state


class FrameStream(torch.utils.data.IterableDataset):
    """Samples of a split, episode by episode, shuffled through a buffer (shuffle=False: in order).

    context: columns whose raw value at the sample's step is yielded as a fourth element (float64 tensor), for
    reports that split errors by regime.
    rank, world_size: in a distributed run (torchrun), each rank reads a disjoint part of the episodes: the episode
    order of an epoch is the same on every rank (seed and epoch), rank r takes every world_size-th episode from
    the r-th, and its DataLoader workers divide those among themselves.
    emphasis: an epoch yields each of the world's decisive steps (its declaration's `decisive`, by the labels among
    the targets) this many times, every other step once: the rare states where a misread label is costly weigh
    more in training."""

    def __init__(self, root: str | Path, split: str | None = "train", targets=None, normalised: bool = True,
                 shuffle: bool = True, seed: int = 0, buffer: int = 2048, moment: Moment | None = None,
                 context: tuple[str, ...] = (), rank: int = 0, world_size: int = 1, cache: FrameCache | None = None,
                 emphasis: int = 1):
        self.data = Dataset(Path(root))
        self.spec = SampleSpec(self.data.declaration, targets, moment, normalised)
        self.shuffle, self.seed, self.buffer = shuffle, seed, buffer
        if not 0 <= rank < world_size:
            raise ValueError(f"rank {rank} is not in a world of {world_size}")
        self.rank, self.world_size = rank, world_size
        self.cache = cache     # decoded frames (perception/frame_cache.py) instead of decoding every epoch
        self.context = tuple(context)
        missing = self.data.missing_columns(self.context)
        if missing:
            raise DatasetError(f"the {self.data.world} dataset {self.data.root} has no column {', '.join(missing)}")
        self.shards = self.data.select(split)
        self.times = self._emphasis(emphasis)   # shard index -> how often each step is yielded (none: once)
        if not self.shards or not len(self):
            raise DatasetError(f"dataset {self.data.root} has no samples in split '{split}'")
        self.epoch = 0
        self.channels_last = False   # samples' memory layout (the values are the same): see _stack

    @property
    def outputs(self) -> tuple[str, ...]:
        return self.spec.outputs

    def _emphasis(self, weight: int) -> dict[int, np.ndarray]:
        """Per shard, how often an epoch yields each step: `weight` for the world's decisive steps by the labels
        among the targets (read as recorded, once, before training), 1 for the others; {} when nothing is
        emphasised. Why only the targets: a car near behind is no decision a network of the cars ahead can learn,
        and its frames would only crowd out those it can."""
        if weight == 1:
            return {}
        declared = worlds.get(self.data.world).decisive
        if not declared:
            raise DatasetError(f"the {self.data.world} world declares no decisive steps to emphasise")
        rule = [(n, bound) for n, bound in declared if n in self.spec.targets]
        if not rule:
            raise DatasetError(f"emphasis: none of the {self.data.world} world's decisive labels "
                               f"({', '.join(dict.fromkeys(n for n, _ in declared))}) is a target")
        names = tuple(dict.fromkeys(n for n, _ in rule))
        times = {}
        for k, shard in enumerate(self.shards):
            table = self.data.reader(shard).labels(names)
            values = {n: table.column(n).to_numpy(zero_copy_only=False).astype(np.float64) for n in names}
            decisive = np.logical_or.reduce([values[n] < bound for n, bound in rule])
            times[k] = np.where(decisive, weight, 1)
        return times

    def samples(self, k: int) -> int:
        """Samples shard k yields in an epoch."""
        starts = self.spec.starts(self.shards[k].frames)
        return int(self.times[k][starts.start:starts.stop].sum()) if k in self.times else len(starts)

    def __len__(self) -> int:
        return sum(self.samples(k) for k in range(len(self.shards)))

    def set_epoch(self, epoch: int) -> None:
        """A new shuffle order per epoch (call before iterating, as with DistributedSampler)."""
        self.epoch = epoch

    def _order(self, rng) -> list[int]:
        """This rank's episodes (shard indices) of the current epoch, in reading order."""
        order = list(range(len(self.shards)))
        if self.shuffle:
            rng.shuffle(order)
        return order[self.rank::self.world_size]

    def _my_shards(self):
        rng = np.random.default_rng([self.seed, self.epoch])
        order = self._order(rng)
        info = torch.utils.data.get_worker_info()
        if info is not None:
            order = order[info.id::info.num_workers]
        return order, rng

    def batches(self, batch_size: int, workers: int = 0) -> int:
        """Whole batches this rank's DataLoader (`workers` processes, drop_last) yields in the current epoch:
        each worker batches its own episodes' samples and drops its last partial batch."""
        order = self._order(np.random.default_rng([self.seed, self.epoch]))
        parts = [order[w::workers] for w in range(workers)] if workers else [order]
        return sum(sum(self.samples(k) for k in part) // batch_size for part in parts)

    def _episode(self, k: int):
        """The samples of shard k as (encoded images, mode, raw targets, context), in step order."""
        spec = self.spec
        reader = self.data.reader(self.shards[k])
        table = reader.labels(tuple(dict.fromkeys(spec.columns + self.context)))
        values = np.stack([table.column(n).to_numpy(zero_copy_only=False).astype(np.float64)
                           for n in spec.targets], axis=1)
        modes = table.column(spec.mode_field).to_numpy() if spec.mode_field else None
        context = np.stack([table.column(n).to_numpy(zero_copy_only=False).astype(np.float64)
                            for n in self.context], axis=1) if self.context else None
        starts = spec.starts(len(values))
        times = self.times.get(k)

        def repeats(step: int) -> range:
            return range(1 if times is None else int(times[step]))

        def sample(step: int, images: list):
            return (images, None if modes is None else int(modes[step]), spec.target_values(values, step),
                    None if context is None else context[step])

        if self.cache is not None:
            cams = [self.cache.frames(self.shards[k], c.name) for c in spec.decl.cameras]
            for step in starts:
                for _ in repeats(step):
                    yield sample(step, [cam[step + dt] for dt in spec.moment.instants for cam in cams])
            return
        instants = spec.moment.instants
        keep = -spec.moment.earliest + 1     # steps of images a sample may reach back to
        window: list[list[bytes]] = []
        step = 0
        for group in reader.iter_row_groups(spec.images):
            columns = [group.column(c).to_pylist() for c in spec.images]
            for row in zip(*columns):
                window.append(list(row))
                if len(window) > keep:
                    window.pop(0)
                if step in starts:
                    for _ in repeats(step):
                        yield sample(step, [img for dt in instants for img in window[len(window) - 1 + dt]])
                step += 1

    def __iter__(self):
        order, rng = self._my_shards()
        pool: list = []
        for k in order:
            for item in self._episode(k):
                pool.append(item)
                if not self.shuffle:
                    yield from self._emit(pool)
                    pool = []
                elif len(pool) >= self.buffer:
                    rng.shuffle(pool)
                    keep = math.ceil(self.buffer / 2)  # emit half, keep half to mix with the next episodes
                    yield from self._emit(pool[keep:])
                    pool = pool[:keep]
        if self.shuffle:
            rng.shuffle(pool)
        yield from self._emit(pool)

    def _emit(self, items):
        for images, mode, raw, context in items:   # images: encoded bytes, or decoded arrays from the cache
            decoded = [decode_image(b) if isinstance(b, bytes) else b for b in images]
            sample = (_stack(decoded, self.channels_last), _mode_tensor(mode), self.spec.target_tensor(raw))
            if self.context:
                yield (*sample, torch.from_numpy(np.asarray(context, dtype=np.float64)))
            else:
                yield sample


def output_labels(outputs) -> tuple[str, ...]:
    """The label each output stands for ("steer+3" -> "steer")."""
    return tuple(base_name(o) for o in outputs)
