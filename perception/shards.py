"""The dataset format (docs/dataset.md), version 2: Parquet shards and a JSON manifest, for any declared world.
The one owner of it: writing and reading both live here. Only pyarrow, numpy and OpenCV: no torch, so generators
and `stats` stay light.

A dataset is a folder:
    manifest.json          the world's declaration, configuration, seed, software versions, and one entry per
                           finished shard (its size and SHA-256, so a damaged shard is found)
    shard-000000.parquet   one episode, row groups of ROW_GROUP steps, in time order
A shard is written to a hidden temporary file and renamed into place when complete, so a shard is either whole or
absent. The split of a step is the split of its episode (SPLIT_RULE), never of single steps.

The columns come from the world's declaration (core/declaration.py): one image column per camera
(`image_<camera>`, PNG or JPEG), one column per truth field (typed by its kind), the declared extra columns, then
the generic `episode`, `step`, `t`, `seed` and `action`. Each step is stored once; a data moment (several
images, labels of later steps) is assembled by the readers (perception/datasets.py).

Version 1 (the highway's first format, before worlds were declared) is refused in one line: regenerate it.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from core.declaration import COLUMN_KIND, DeclarationError, WorldDeclaration
from core.files import atomic_write, reclaim_temporaries

FORMAT = "drivestudio-dataset"
VERSION = 2
ROW_GROUP = 64
MANIFEST = "manifest.json"
MANIFEST_LIMIT = 64 << 20          # [bytes] a manifest larger than this is not one of ours
ENCODINGS = ("png", "jpeg")
SPLIT_RULE = "episode % 10: 0-7 train, 8 validation, 9 test"
GENERIC = ("episode", "step", "t", "seed", "action")   # columns every dataset has, after the world's own

_SCALAR = {"f32": pa.float32(), "f64": pa.float64(), "i8": pa.int8(), "i32": pa.int32(), "i64": pa.int64(),
           "bool": pa.bool_(), "str": pa.string()}


class DatasetError(ValueError):
    """A dataset that cannot be read: missing manifest, corrupt or truncated shard, missing labels."""


def image_column(camera: str) -> str:
    return f"image_{camera}"


def _column_type(kind: str) -> pa.DataType:
    m = COLUMN_KIND.fullmatch(kind)
    assert m is not None   # a WorldDeclaration checks its column kinds
    base, size, many = m.group(1), m.group(2), m.group(3)
    t = _SCALAR[base]
    if size:
        t = pa.list_(t, int(size[1:-1]))
    if many:
        t = pa.list_(t)
    return t


def schema_for(decl: WorldDeclaration) -> pa.Schema:
    """The shard schema of a world: images, truth fields, declared columns, then the generic columns."""
    fields = [(image_column(c.name), pa.binary()) for c in decl.cameras]
    fields += [(q.name, _SCALAR[q.kind]) for q in decl.truth]
    fields += [(c.name, _column_type(c.kind)) for c in decl.columns]
    fields += [("episode", pa.int32()), ("step", pa.int32()), ("t", pa.float64()), ("seed", pa.int64()),
               ("action", pa.list_(pa.float32(), len(decl.action)))]
    return pa.schema(fields)


def label_columns(decl: WorldDeclaration) -> tuple[str, ...]:
    """Every column but the images."""
    return tuple(n for n in schema_for(decl).names if not n.startswith("image_"))


def split_of(episode: int) -> str:
    """The split of an episode (SPLIT_RULE): whole episodes, so no two neighbouring steps straddle splits."""
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


def file_digest(path) -> tuple[int, str]:
    """(size in bytes, SHA-256 hex) of a file."""
    h = hashlib.sha256()
    size = 0
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            h.update(chunk)
            size += len(chunk)
    return size, h.hexdigest()


# --- writing -------------------------------------------------------------------------------------------------
class ShardWriter:
    """Collects one episode's steps and writes them as one shard, atomically, on close()."""

    def __init__(self, path: Path, decl: WorldDeclaration, encoding: str = "png", quality: int = 95):
        if encoding not in ENCODINGS:
            raise ValueError(f"unknown image encoding '{encoding}' (choose from {', '.join(ENCODINGS)})")
        self.path, self.decl, self.encoding, self.quality = Path(path), decl, encoding, quality
        self.schema = schema_for(decl)
        self._images: list[list[bytes]] = [[] for _ in decl.cameras]
        self._records: list[np.ndarray] = []
        self._columns: dict[str, list] = {c.name: [] for c in decl.columns}
        self._generic: dict[str, list] = {n: [] for n in GENERIC}

    def __len__(self) -> int:
        return len(self._records)

    def add(self, images, record, columns: dict, *, episode: int, step: int, t: float, seed: int, action) -> None:
        """One step: the images (one per camera, declaration order), the truth record (float64, declaration
        order), the declared extra columns by name, and the generic fields."""
        if isinstance(images, np.ndarray):
            images = (images,)
        if len(images) != len(self._images):
            raise ValueError(f"expected {len(self._images)} image(s), got {len(images)}")
        for store, img in zip(self._images, images):
            store.append(encode_image(img, self.encoding, self.quality))
        self._records.append(np.asarray(record, dtype=np.float64))
        for name, store in self._columns.items():
            store.append(columns[name])
        g = self._generic
        g["episode"].append(episode)
        g["step"].append(step)
        g["t"].append(t)
        g["seed"].append(seed)
        g["action"].append(np.asarray(action, dtype=np.float32).tolist())

    def table(self) -> pa.Table:
        decl = self.decl
        arrays: dict[str, Any] = {image_column(c.name): store for c, store in zip(decl.cameras, self._images)}
        records = np.stack(self._records) if self._records else np.zeros((0, len(decl.truth)))
        for i, q in enumerate(decl.truth):
            col = records[:, i]
            arrays[q.name] = col.astype(bool) if q.kind == "bool" else np.round(col).astype(
                np.dtype(q.kind.replace("i", "int"))) if q.kind.startswith("i") else col
        arrays.update(self._columns)
        arrays.update(self._generic)
        return pa.table(arrays, schema=self.schema)

    def close(self) -> dict:
        """Write the shard (to a temporary name, then renamed into place); returns {frames, size, sha256}."""
        table = self.table()
        strings = [c.name for c in self.decl.columns if c.kind == "str"]

        def write(f) -> None:
            pq.write_table(table, f, row_group_size=ROW_GROUP, compression="none",
                           use_dictionary=strings or False, write_statistics=False)

        atomic_write(self.path, write)
        size, digest = file_digest(self.path)
        return {"frames": table.num_rows, "size": size, "sha256": digest}


def clean_temporaries(root: Path) -> int:
    """Remove half-written shards and manifests left by killed runs; returns how many."""
    n = reclaim_temporaries(root)
    for p in list(Path(root).glob(".shard-*.tmp")) + list(Path(root).glob(f".{MANIFEST}.*.tmp")):
        p.unlink(missing_ok=True)   # no writer runs here while the caller holds the dataset's lock
        n += 1
    return n


# --- the manifest --------------------------------------------------------------------------------------------
def read_manifest(root: Path) -> dict:
    """The manifest of a dataset folder, or DatasetError in one line."""
    path = Path(root) / MANIFEST
    try:
        if path.stat().st_size > MANIFEST_LIMIT:
            raise DatasetError(f"{path} is too large to be a dataset manifest")
        manifest = json.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        raise DatasetError(f"{root} is not a dataset: no {MANIFEST}") from None
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as e:
        what = "not UTF-8" if isinstance(e, UnicodeDecodeError) else "not valid JSON"
        raise DatasetError(f"{path} is corrupt ({what}); regenerate the dataset or restore the manifest") from None
    except IsADirectoryError:
        raise DatasetError(f"{path} is a folder, not a manifest") from None
    except OSError as e:
        raise DatasetError(f"cannot read {path}: {e.strerror}") from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise DatasetError(f"{path} is not a drivestudio dataset manifest")
    if manifest.get("version") == 1:
        raise DatasetError(f"{path} is a dataset of format version 1 (drivestudio 0.1), which is no longer read; "
                           "generate it again with `drivestudio generate`")
    if manifest.get("version") != VERSION:
        raise DatasetError(f"{path} has dataset format version {manifest.get('version')}; this reader reads "
                           f"version {VERSION}")
    if not isinstance(manifest.get("shards", []), list):
        raise DatasetError(f"{path} is corrupt: its shard list is not a list")
    return manifest


def write_manifest(root: Path, manifest: dict) -> None:
    """Atomically replace the manifest (always version 2)."""
    body = {k: v for k, v in manifest.items() if k not in ("format", "version")}
    text = json.dumps({"format": FORMAT, "version": VERSION, **body}, indent=1) + "\n"
    atomic_write(Path(root) / MANIFEST, text.encode())


def manifest_declaration(manifest: dict) -> WorldDeclaration:
    try:
        return WorldDeclaration.from_json(manifest["world"])
    except (KeyError, DeclarationError) as e:
        raise DatasetError(f"the manifest does not declare its world ({e})") from None


# --- reading -------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ShardInfo:
    file: str
    episode: int
    frames: int
    split: str
    params: dict = field(default_factory=dict)   # what the world's plan chose for the episode (track, lanes, ...)
    size: int | None = None
    sha256: str | None = None

    @classmethod
    def from_entry(cls, entry: dict) -> ShardInfo:
        try:
            return cls(str(entry["file"]), int(entry["episode"]), int(entry["frames"]), str(entry["split"]),
                       dict(entry.get("params", {})), entry.get("size"), entry.get("sha256"))
        except (KeyError, TypeError, ValueError):
            raise DatasetError(f"the manifest lists a shard it does not describe: {str(entry)[:80]}") from None

    def entry(self) -> dict:
        return {"file": self.file, "episode": self.episode, "frames": self.frames, "split": self.split,
                "params": self.params, "size": self.size, "sha256": self.sha256}


class ShardReader:
    """Random and sequential access to one shard, with its last row group kept."""

    def __init__(self, path: Path, decl: WorldDeclaration):
        self.path, self.decl = Path(path), decl
        self.schema = schema_for(decl)
        try:
            self._file = pq.ParquetFile(self.path, memory_map=True)
        except FileNotFoundError:
            raise DatasetError(f"shard {self.path} is missing") from None
        except (pa.ArrowException, OSError) as e:
            raise DatasetError(f"shard {self.path} is corrupt or truncated: {str(e).splitlines()[0]}") from None
        meta = self._file.metadata
        names = self._file.schema_arrow.names
        if names != self.schema.names:
            raise DatasetError(f"shard {self.path} does not have the columns of a {decl.name} dataset")
        sizes = [meta.row_group(i).num_rows for i in range(meta.num_row_groups)]
        self._starts = np.cumsum([0] + sizes)
        self._cached: tuple[int, pa.Table] | None = None

    def __len__(self) -> int:
        return int(self._starts[-1])

    def row_group(self, g: int, columns=None) -> pa.Table:
        try:
            table = self._file.read_row_group(g, columns=None if columns is None else list(columns))
        except (pa.ArrowException, OSError) as e:
            raise DatasetError(f"shard {self.path} is corrupt or truncated (row group {g}): "
                               f"{str(e).splitlines()[0]}") from None
        return table

    def row(self, i: int) -> tuple[tuple, dict]:
        """Step i: (images, one RGB array per camera; {column: value} of every other column)."""
        if not 0 <= i < len(self):
            raise IndexError(i)
        g = int(np.searchsorted(self._starts, i, side="right") - 1)
        if self._cached is None or self._cached[0] != g:
            self._cached = (g, self.row_group(g))
        table = self._cached[1]
        k = i - int(self._starts[g])
        images = tuple(decode_image(table.column(image_column(c.name))[k].as_py()) for c in self.decl.cameras)
        record = {name: table.column(name)[k].as_py() for name in label_columns(self.decl)}
        return images, record

    def labels(self, columns=None) -> pa.Table:
        """Every step's labels (the named columns, default all but the images); images not read."""
        columns = label_columns(self.decl) if columns is None else tuple(columns)
        try:
            table = self._file.read(columns=list(columns))
        except (pa.ArrowException, OSError) as e:
            raise DatasetError(f"shard {self.path} is corrupt or truncated: {str(e).splitlines()[0]}") from None
        return table

    def iter_row_groups(self, columns=None):
        for g in range(len(self._starts) - 1):
            yield self.row_group(g, columns)


class Dataset:
    """A dataset folder: its manifest, its world's declaration and its shards, split by episode."""

    def __init__(self, root: Path):
        self.root = Path(root)
        if not self.root.is_dir():
            raise DatasetError(f"no dataset at {self.root}: not a folder")
        self.manifest = read_manifest(self.root)
        self.version = int(self.manifest["version"])
        self.declaration = manifest_declaration(self.manifest)
        self.shards = sorted((ShardInfo.from_entry(s) for s in self.manifest.get("shards", [])),
                             key=lambda s: s.episode)
        if not self.shards:
            raise DatasetError(f"dataset {self.root} has no finished shards yet")

    @property
    def world(self) -> str:
        return self.declaration.name

    @property
    def renderers(self) -> tuple[str, ...]:
        """The renderers that drew the frames: one for a generated dataset, every source's for a merged one; none for
        a dataset that does not say."""
        m = self.manifest
        named = m.get("renderers") or ([m["renderer"]] if m.get("renderer") else [])
        return tuple(sorted({str(r) for r in named}))

    def select(self, split: str | None = None) -> list[ShardInfo]:
        if split in (None, "all"):
            return list(self.shards)
        if split not in ("train", "val", "test"):
            raise DatasetError(f"unknown split '{split}' (train, val, test or all)")
        return [s for s in self.shards if s.split == split]

    def frames(self, split: str | None = None) -> int:
        return sum(s.frames for s in self.select(split))

    def reader(self, shard: ShardInfo) -> ShardReader:
        path = self.root / shard.file
        if shard.size is not None:
            try:
                size = path.stat().st_size
            except FileNotFoundError:
                raise DatasetError(f"shard {path} is missing") from None
            if size != shard.size:
                raise DatasetError(f"shard {path} is damaged: {size} bytes, the manifest says {shard.size}")
        return ShardReader(path, self.declaration)

    def missing_columns(self, names) -> list[str]:
        """Which of `names` this dataset lacks."""
        have = set(label_columns(self.declaration))
        return [n for n in names if n not in have]

    def labels(self, split: str | None = None, columns=None) -> dict[str, np.ndarray]:
        """Label columns of every step of a split as numpy arrays (list columns as object arrays)."""
        columns = label_columns(self.declaration) if columns is None else tuple(columns)
        missing = self.missing_columns(columns)
        if missing:
            raise DatasetError(f"the {self.world} dataset {self.root} has no column {', '.join(missing)}")
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

    def verify(self, shard: ShardInfo) -> str | None:
        return verify_shard(self.root, shard)


def verify_shard(root: Path, shard: ShardInfo) -> str | None:
    """None when the shard is whole (size and SHA-256 as the manifest lists them), else what is wrong."""
    path = Path(root) / shard.file
    if not path.is_file():
        return "missing"
    if shard.sha256 is None:
        return None
    size, digest = file_digest(path)
    if size != shard.size:
        return f"{size} bytes instead of {shard.size}"
    if digest != shard.sha256:
        return "its checksum differs from the manifest's"
    return None

