"""Content fingerprints (perception/fingerprint.py): the same data written as other bytes keeps its fingerprint, one
pixel or one label changes the images' or the labels' fingerprint alone, the frame cache changes nothing, and a
network's fingerprint is the digest of its tensors."""
import json
import shutil

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from perception.fingerprint import _column_bytes, dataset_fingerprint, network_fingerprint
from perception.frame_cache import prepare_cache
from perception.shards import MANIFEST, Dataset, decode_image, file_digest
from tests.perception.frames import dataset


def copy_of(tmp_path, name="copy"):
    out = tmp_path / name
    shutil.copytree(dataset(), out, ignore=shutil.ignore_patterns(".frames"))
    return out


def rewrite_shard(root, index, change, **write_options):
    """Shard `index` of the dataset at root, its table passed through change(table), written back with
    `write_options` and listed in the manifest with its new size and checksum (so it reads as whole)."""
    ds = Dataset(root)
    shard = ds.shards[index]
    path = root / shard.file
    table = change(pq.read_table(path))
    pq.write_table(table, path, **write_options)
    manifest = json.loads((root / MANIFEST).read_text())
    entry = next(e for e in manifest["shards"] if e["file"] == shard.file)
    entry["size"], entry["sha256"] = file_digest(path)
    (root / MANIFEST).write_text(json.dumps(manifest))


def replace_column(table, name, values):
    return table.set_column(table.column_names.index(name), name, pa.array(values, type=table.schema.field(name).type))


def reencode(table, pixel=None):
    """Every frame re-encoded at PNG's highest compression (other bytes, the same pixels); with `pixel`, step 0's
    pixel (row, column) changed too."""
    frames = []
    for k, data in enumerate(table.column("image_front").to_pylist()):
        rgb = decode_image(data)
        if pixel is not None and k == 0:
            rgb[pixel] = 255 - rgb[pixel]
        ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 9])
        frames.append(buf.tobytes())
    return replace_column(table, "image_front", frames)


@pytest.fixture(scope="module")
def original():
    return dataset_fingerprint(Dataset(dataset()))


def test_the_same_frames_and_labels_written_as_other_bytes_keep_their_fingerprint(tmp_path, original):
    root = copy_of(tmp_path)
    before = file_digest(root / Dataset(root).shards[0].file)
    rewrite_shard(root, 0, reencode, compression="zstd", row_group_size=5)
    assert file_digest(root / Dataset(root).shards[0].file) != before   # other bytes ...
    assert dataset_fingerprint(Dataset(root)) == original                 # ... the same content


def test_one_pixel_changes_the_images_fingerprint_alone(tmp_path, original):
    root = copy_of(tmp_path)
    rewrite_shard(root, 3, lambda t: reencode(t, pixel=(100, 140, 1)))
    changed = dataset_fingerprint(Dataset(root))
    assert changed["images"] != original["images"]
    assert changed["labels"] == original["labels"] and changed["frames"] == original["frames"]


def test_one_label_changes_the_labels_fingerprint_alone(tmp_path, original):
    root = copy_of(tmp_path)

    def nudge(table):
        values = table.column("dist_MM").to_numpy().copy()
        values[5] = np.nextafter(values[5], np.float32(np.inf), dtype=np.float32)   # the smallest change a float32 has
        return replace_column(table, "dist_MM", values)

    rewrite_shard(root, 1, nudge)
    changed = dataset_fingerprint(Dataset(root))
    assert changed["labels"] != original["labels"] and changed["images"] == original["images"]


def test_frames_read_from_the_frame_cache_give_the_same_fingerprint(tmp_path, original):
    root = copy_of(tmp_path)
    ds = Dataset(root)
    prepare_cache(ds, ds.select("train"), log=lambda *a: None)
    assert dataset_fingerprint(Dataset(root)) == original
    assert dataset_fingerprint(ds, "train") != dataset_fingerprint(ds, "val")
    assert dataset_fingerprint(ds, "train")["frames"] == ds.frames("train")
    assert dataset_fingerprint(ds, images=False) == {**original, "images": None}


def test_list_and_string_columns_keep_their_row_boundaries():
    a = _column_bytes(pa.chunked_array([pa.array([[1.0], [2.0, 3.0]])]))
    b = _column_bytes(pa.chunked_array([pa.array([[1.0, 2.0], [3.0]])]))
    assert a != b
    assert _column_bytes(pa.chunked_array([pa.array(["ab", "c"])])) != \
        _column_bytes(pa.chunked_array([pa.array(["a", "bc"])]))
    # the same values chunked differently hash the same
    assert _column_bytes(pa.chunked_array([pa.array([1, 2]), pa.array([3])])) == \
        _column_bytes(pa.chunked_array([pa.array([1, 2, 3])]))
    # a null is not a zero
    assert _column_bytes(pa.chunked_array([pa.array([0.0, None])])) != \
        _column_bytes(pa.chunked_array([pa.array([0.0, 0.0])]))


def test_a_networks_fingerprint_is_the_digest_of_its_tensors():
    import torch

    from perception.checkpoint import tensor_digest
    from tests.perception.frames import alexnet_checkpoint

    path, _ = alexnet_checkpoint()
    ckpt = torch.load(path, weights_only=True)
    assert network_fingerprint(path) == ckpt["state_sha256"] == tensor_digest(ckpt["state_dict"])
    state = dict(ckpt["state_dict"])
    key = next(k for k, v in state.items() if v.is_floating_point() and v.numel() > 10)
    state[key] = state[key].contiguous().clone()
    state[key].view(-1)[0] += 1e-3
    assert tensor_digest(state) != network_fingerprint(path)


def test_stats_prints_the_fingerprint_only_when_asked(run_cli, tmp_path, original):
    cmd = ["stats", dataset()]
    r = run_cli(*cmd, "--fingerprint", "--out", tmp_path / "a")
    assert r.returncode == 0, r.stderr
    assert f"labels {original['labels']}, images {original['images']}" in r.stdout
    assert json.loads((tmp_path / "a" / "stats.json").read_text())["fingerprint"] == original
    r = run_cli(*cmd, "--out", tmp_path / "b")
    assert r.returncode == 0, r.stderr
    assert "fingerprint" not in r.stdout
    assert "fingerprint" not in json.loads((tmp_path / "b" / "stats.json").read_text())
