"""Merging datasets of one world into one (data aggregation rounds): an ordinary dataset that every reader,
`stats`, `train` and `evaluate` read like any other.

Each source's shards are copied with their episodes renumbered by the source's offset (source k: + k x
EPISODE_OFFSET, a multiple of 10, so that the split rule gives every episode the split it had): no two episodes of
the merged set share a number, and a copied shard is the source shard with only its `episode` column changed (the
images are copied byte for byte, not re-encoded). A source given as `train_only` has all its episodes in the
training split (the frames a learned driver visited, aggregated for training: the original validation and test
episodes stay what they were). The manifest lists where each shard came from. Writing is atomic per shard and the
manifest comes last, so an interrupted merge leaves no dataset that looks whole.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from core.files import atomic_write, check_output_dir, make_dir
from perception.shards import (
    MANIFEST,
    SPLIT_RULE,
    Dataset,
    DatasetError,
    ShardInfo,
    file_digest,
    shard_name,
    write_manifest,
)

EPISODE_OFFSET = 100_000    # episodes of source k are numbered k * EPISODE_OFFSET + their own number


@dataclass(frozen=True)
class Source:
    root: Path
    train_only: bool = False    # every episode of this source goes to the training split


def merge(out: Path, sources: list[Source], log=print) -> Dataset:
    """Write the dataset at `out` holding every shard of `sources` (all of one world); returns it."""
    if not sources:
        raise DatasetError("nothing to merge")
    datasets = [Dataset(Path(s.root)) for s in sources]
    first = datasets[0].declaration
    for s, d in zip(sources, datasets):
        if d.declaration.fingerprint() != first.fingerprint():
            raise DatasetError(f"{s.root} is a dataset of another world or camera than {sources[0].root}; only "
                               "datasets of one world merge")
        if len(d.shards) and max(sh.episode for sh in d.shards) >= EPISODE_OFFSET:
            raise DatasetError(f"{s.root} has episode numbers of {EPISODE_OFFSET} or more; it cannot be merged")
    out = make_dir(check_output_dir(out, "dataset folder"))
    if (out / MANIFEST).exists():
        raise DatasetError(f"{out} holds a dataset already; merge into a new folder")
    t0 = time.perf_counter()
    entries = []
    for k, (s, d) in enumerate(zip(sources, datasets)):
        for shard in d.shards:
            entries.append(_copy(d, shard, out, k * EPISODE_OFFSET, "train" if s.train_only else shard.split))
    manifest = {"world": first.to_json(), "config": {"merged": [{"root": str(Path(s.root).resolve()),
                                                                "train_only": s.train_only,
                                                                "frames": d.frames()}
                                                               for s, d in zip(sources, datasets)]},
                "renderers": sorted({r for d in datasets for r in d.renderers}),
                "split_rule": SPLIT_RULE + "; a train-only source's episodes: train",
                "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "shards": entries,
                "frames": sum(e["frames"] for e in entries), "complete": True}
    write_manifest(out, manifest)
    log(f"merged {len(sources)} datasets ({manifest['frames']} frames in {len(entries)} episodes) into {out} "
        f"({time.perf_counter() - t0:.0f} s)")
    return Dataset(out)


def _copy(data: Dataset, shard: ShardInfo, out: Path, offset: int, split: str) -> dict:
    """One shard, its episode renumbered; the manifest entry of the copy."""
    episode = shard.episode + offset
    table = pq.read_table(data.root / shard.file)
    i = table.schema.get_field_index("episode")
    table = table.set_column(i, table.schema.field(i), pa.array([episode] * table.num_rows,
                                                                type=table.schema.field(i).type))
    target = out / shard_name(episode)
    meta = pq.ParquetFile(data.root / shard.file).metadata
    rows = meta.row_group(0).num_rows if meta.num_row_groups else table.num_rows
    strings = [c.name for c in data.declaration.columns if c.kind == "str"]

    def write(f) -> None:   # as perception/shards.py's ShardWriter writes a shard
        pq.write_table(table, f, row_group_size=rows, compression="none", use_dictionary=strings or False,
                       write_statistics=False)

    atomic_write(target, write)
    size, digest = file_digest(target)
    return ShardInfo(target.name, episode, shard.frames, split, dict(shard.params), size, digest).entry()
