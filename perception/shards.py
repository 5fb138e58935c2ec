"""The dataset format (docs/dataset.md): Parquet shards and a JSON manifest. The one owner of it: writing and
reading both live here. Only pyarrow, numpy and OpenCV: no torch, so generators and `stats` stay light.

A dataset is a folder:
    manifest.json          configuration, seed, renderer, software versions, and one entry per finished shard
    shard-000000.parquet   one episode of driving, row groups of ROW_GROUP frames
A shard is written to a hidden temporary file and renamed into place when complete, so a shard is either
whole or absent. The split of a frame is the split of its episode (SPLIT_RULE), never of single frames.
"""
from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from shm_bridge.vocabulary import INDICATORS

FORMAT = "drivestudio-dataset"
VERSION = 1
ROW_GROUP = 64
MANIFEST = "manifest.json"
ENCODINGS = ("png", "jpeg")
SPLIT_RULE = "episode % 10: 0-7 train, 8 validation, 9 test"

SCHEMA = pa.schema(
    [("image", pa.binary())]
    + [(name, pa.float32()) for name in INDICATORS]
    + [("lanes_left", pa.int8()), ("lanes", pa.int8()), ("speed", pa.float32()), ("lane_width", pa.float32()),
       ("in_lane", pa.bool_()), ("on_marking", pa.bool_()),
       ("episode", pa.int32()), ("step", pa.int32()), ("t", pa.float32()), ("track", pa.string()),
       ("seed", pa.int64()), ("perturbation", pa.string()),
       ("ego", pa.list_(pa.float64(), 5)), ("cars", pa.list_(pa.list_(pa.float32(), 5))),
       ("action", pa.list_(pa.float32(), 3))]
)
LABEL_COLUMNS = tuple(n for n in SCHEMA.names if n != "image")


class DatasetError(ValueError):
    """A dataset that cannot be read: missing manifest, corrupt or truncated shard, missing labels."""


def split_of(episode: int) -> str:
    """The split of an episode (SPLIT_RULE): whole episodes, so no two neighbouring frames straddle splits."""
    k = int(episode) % 10
    return "test" if k == 9 else "val" if k == 8 else "train"


def shard_name(episode: int) -> str:
    return f"shard-{int(episode):06d}.parquet"


# --- images --------------------------------------------------------------------------------------------------
def encode_image(rgb: np.ndarray, encoding: str = "png", quality: int = 95) -> bytes:
    bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    if encoding == "png":
        # no row filter instead of libpng's per-row search: our flat-shaded frames compress best unfiltered
        # (measured on 20 frames of a default set: 0.40 ms and 5.0 kB a frame; SUB 0.51 ms, 6.1 kB; the
        # adaptive default 1.7 ms, 5.3 kB), and decode as fast
        ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1,
                                             cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_NONE])
    elif encoding == "jpeg":
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    else:
        raise ValueError(f"unknown image encoding '{encoding}' (choose from {', '.join(ENCODINGS)})")
    if not ok:
        raise ValueError("image encoding failed")
    return buf.tobytes()


def decode_image(data: bytes) -> np.ndarray:
    """PNG or JPEG bytes to (h, w, 3) uint8 RGB."""
    bgr = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if bgr is None:
        raise DatasetError("an image in the shard cannot be decoded")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


# --- writing -------------------------------------------------------------------------------------------------
class ShardWriter:
    """Collects one episode's frames and writes them as one shard, atomically, on close()."""

    def __init__(self, path: Path, encoding: str = "png", quality: int = 95):
        if encoding not in ENCODINGS:
            raise ValueError(f"unknown image encoding '{encoding}' (choose from {', '.join(ENCODINGS)})")
        self.path, self.encoding, self.quality = Path(path), encoding, quality
        self._columns: dict[str, list] = {name: [] for name in SCHEMA.names}

    def __len__(self) -> int:
        return len(self._columns["image"])

    def add(self, image: np.ndarray, record: dict) -> None:
        """One frame: the RGB image and a record with every other column of SCHEMA (indicators by name)."""
        self._columns["image"].append(encode_image(image, self.encoding, self.quality))
        for name in LABEL_COLUMNS:
            self._columns[name].append(record[name])

    def close(self) -> int:
        """Write the shard (to a temporary name, then renamed into place); returns the number of frames."""
        table = pa.table(self._columns, schema=SCHEMA)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = _temporary(self.path)
        try:
            pq.write_table(table, tmp, row_group_size=ROW_GROUP, compression="none",
                           use_dictionary=["track", "perturbation"], write_statistics=False)
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return table.num_rows


def _temporary(path: Path) -> Path:
    """A hidden name beside `path` for writing before the rename (created with the usual permissions)."""
    return path.parent / f".{path.name}.{os.getpid()}.{time.monotonic_ns()}.tmp"


def clean_temporaries(root: Path) -> int:
    """Remove half-written shards left by a killed run; returns how many."""
    n = 0
    for p in list(Path(root).glob(".shard-*.tmp")) + list(Path(root).glob(f".{MANIFEST}.*.tmp")):
        p.unlink(missing_ok=True)
        n += 1
    return n


# --- the manifest --------------------------------------------------------------------------------------------
def read_manifest(root: Path) -> dict:
    path = Path(root) / MANIFEST
    try:
        manifest = json.loads(path.read_text())
    except FileNotFoundError:
        raise DatasetError(f"{root} is not a dataset: no {MANIFEST}") from None
    except json.JSONDecodeError as e:
        raise DatasetError(f"{path} is corrupt: {e.msg} at line {e.lineno}") from None
    if manifest.get("format") != FORMAT:
        raise DatasetError(f"{path} is not a drivestudio dataset manifest")
    if manifest.get("version") != VERSION:
        raise DatasetError(f"{path} has dataset format version {manifest.get('version')}; this reader reads "
                           f"version {VERSION}")
    return manifest


def write_manifest(root: Path, manifest: dict) -> None:
    """Atomically replace the manifest."""
    path = Path(root) / MANIFEST
    tmp = _temporary(path)
    with open(tmp, "w") as f:
        json.dump({"format": FORMAT, "version": VERSION, **manifest}, f, indent=1)
        f.write("\n")
    os.replace(tmp, path)


# --- reading -------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ShardInfo:
    file: str
    episode: int
    frames: int
    split: str
    track: str
    lanes: int


class ShardReader:
    """Random and sequential access to one shard, with its last row group's images kept decoded-ready."""

    def __init__(self, path: Path):
        self.path = Path(path)
        try:
            self._file = pq.ParquetFile(self.path, memory_map=True)
        except FileNotFoundError:
            raise DatasetError(f"shard {self.path} is missing") from None
        except (pa.ArrowException, OSError) as e:
            raise DatasetError(f"shard {self.path} is corrupt or truncated: {e}") from None
        meta = self._file.metadata
        if self._file.schema_arrow.names != SCHEMA.names:
            raise DatasetError(f"shard {self.path} does not have the columns of a drivestudio dataset")
        sizes = [meta.row_group(i).num_rows for i in range(meta.num_row_groups)]
        self._starts = np.cumsum([0] + sizes)
        self._cached: tuple[int, pa.Table] | None = None

    def __len__(self) -> int:
        return int(self._starts[-1])

    def row_group(self, g: int, columns=None) -> pa.Table:
        try:
            return self._file.read_row_group(g, columns=columns)
        except (pa.ArrowException, OSError) as e:
            raise DatasetError(f"shard {self.path} is corrupt or truncated (row group {g}): {e}") from None

    def row(self, i: int) -> tuple[np.ndarray, dict]:
        """Frame i: (RGB image, {column: value})."""
        g = int(np.searchsorted(self._starts, i, side="right") - 1)
        if self._cached is None or self._cached[0] != g:
            self._cached = (g, self.row_group(g))
        table = self._cached[1]
        k = i - int(self._starts[g])
        record = {name: table.column(name)[k].as_py() for name in LABEL_COLUMNS}
        return decode_image(table.column("image")[k].as_py()), record

    def labels(self, columns=LABEL_COLUMNS) -> pa.Table:
        """Every frame's labels, images not read."""
        try:
            return self._file.read(columns=list(columns))
        except (pa.ArrowException, OSError) as e:
            raise DatasetError(f"shard {self.path} is corrupt or truncated: {e}") from None

    def iter_row_groups(self):
        for g in range(len(self._starts) - 1):
            yield self.row_group(g)


class Dataset:
    """A dataset folder: its manifest and shards, split by episode."""

    def __init__(self, root: Path):
        self.root = Path(root)
        if not self.root.is_dir():
            raise DatasetError(f"no dataset at {self.root}: not a folder")
        self.manifest = read_manifest(self.root)
        self.shards = [ShardInfo(**s) for s in sorted(self.manifest.get("shards", []), key=lambda s: s["episode"])]
        if not self.shards:
            raise DatasetError(f"dataset {self.root} has no finished shards yet")

    def select(self, split: str | None = None) -> list[ShardInfo]:
        if split in (None, "all"):
            return list(self.shards)
        if split not in ("train", "val", "test"):
            raise DatasetError(f"unknown split '{split}' (train, val, test or all)")
        return [s for s in self.shards if s.split == split]

    def frames(self, split: str | None = None) -> int:
        return sum(s.frames for s in self.select(split))

    def reader(self, shard: ShardInfo) -> ShardReader:
        return ShardReader(self.root / shard.file)

    def labels(self, split: str | None = None, columns=LABEL_COLUMNS) -> dict[str, np.ndarray]:
        """Label columns of every frame of a split as numpy arrays (ego/cars/action as lists)."""
        tables = [self.reader(s).labels(columns) for s in self.select(split)]
        if not tables:
            return {c: np.zeros(0) for c in columns}
        table = pa.concat_tables(tables)
        out = {}
        for c in columns:
            col = table.column(c)
            out[c] = np.asarray(col.to_pylist(), dtype=object) if pa.types.is_list(col.type) or \
                pa.types.is_fixed_size_list(col.type) else col.to_numpy()
        return out
