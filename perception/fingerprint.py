"""Content fingerprints: whether two datasets or two networks are the same, whatever machine made them.

A shard's file checksum (in the manifest) says whether a file is whole, but two machines can write the same frames
and labels as different bytes (the PNG compressor's choices, Parquet's metadata). A dataset's fingerprint hashes what
a training reads instead: every label column, value by value, and every frame decoded to its pixels, in episode and
step order. A network's fingerprint is the SHA-256 of its tensors that its checkpoint stores (perception/
checkpoint.py). `drivestudio stats DATA --fingerprint` prints a dataset's; the recipes write theirs for every dataset
and network they make, so two runs (two CPUs, two versions) can be compared step by step: the first step whose
fingerprint differs is where they part.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from perception.shards import Dataset, ShardInfo, ShardReader, decode_image, image_column, label_columns


def _column_bytes(col: pa.ChunkedArray) -> list[bytes]:
    """A column's values as bytes that do not depend on how Arrow chunked or laid them out: list columns flattened
    (with each row's length, so [[1], [2, 3]] and [[1, 2], [3]] differ), strings joined with their lengths, numbers
    as their little-endian bytes (a NaN by its bit pattern) after a mask of the nulls."""
    arr = col.combine_chunks() if isinstance(col, pa.ChunkedArray) else col
    if pa.types.is_list(arr.type) or pa.types.is_fixed_size_list(arr.type):
        lengths = pc.fill_null(pc.list_value_length(arr), 0).to_numpy(zero_copy_only=False).astype("<i8")
        return [lengths.tobytes(), *_column_bytes(arr.flatten())]
    if pa.types.is_string(arr.type) or pa.types.is_large_string(arr.type):
        return ["\0".join(f"{len(s)}:{s}" for s in (v if v is not None else "" for v in arr.to_pylist())).encode()]
    values = arr.to_numpy(zero_copy_only=False)
    nulls = np.asarray(arr.is_null().to_numpy(zero_copy_only=False), dtype=np.uint8)
    if values.dtype == object:   # nulls in a numeric column
        values = np.array([0 if v is None else v for v in values])
    return [nulls.tobytes(), np.ascontiguousarray(values).astype(values.dtype.newbyteorder("<")).tobytes()]


def dataset_fingerprint(ds: Dataset, split: str | None = None, images: bool = True) -> dict:
    """{"frames", "labels": SHA-256 of every label column, "images": SHA-256 of every decoded frame (None when
    `images` is False)} over a split's episodes in order. Frames come from the dataset's frame cache where it holds
    them (the decoded stored images, bit for bit: perception/frame_cache.py), else are decoded (about a millisecond a
    frame)."""
    from perception.frame_cache import FrameCache  # numpy, tqdm: light
    cache = FrameCache(ds)
    columns = label_columns(ds.declaration)
    cameras = [c.name for c in ds.declaration.cameras]
    h_labels, h_images = hashlib.sha256(), hashlib.sha256()
    frames = 0
    for shard in ds.select(split):
        reader = ds.reader(shard)
        table = reader.labels(columns)
        h_labels.update(f"episode {shard.episode}: {table.num_rows}\0".encode())
        for name in columns:
            h_labels.update(f"{name}\0".encode())
            for part in _column_bytes(table.column(name)):
                h_labels.update(len(part).to_bytes(8, "little"))
                h_labels.update(part)
        if images:
            for camera in cameras:
                _hash_frames(h_images, reader, cache, shard, camera)
        frames += table.num_rows
    return {"frames": frames, "labels": h_labels.hexdigest(), "images": h_images.hexdigest() if images else None}


def _hash_frames(h, reader: ShardReader, cache, shard: ShardInfo, camera: str) -> None:
    if not cache.missing([shard]):
        h.update(np.ascontiguousarray(cache.frames(shard, camera)).data)   # the map itself, not a copy
        return
    for group in reader.iter_row_groups([image_column(camera)]):
        for data in group.column(0).to_pylist():
            h.update(decode_image(data).tobytes())


def network_fingerprint(path: Path) -> str:
    """The SHA-256 of a checkpoint's tensors (computed, so checkpoints written before it was stored have one too)."""
    from perception.checkpoint import load_checkpoint, tensor_digest  # torch: only for networks
    return tensor_digest(load_checkpoint(path)["state_dict"])
