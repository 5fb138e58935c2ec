"""The frame cache (perception/frame_cache.py): every cached frame is the stored frame decoded, training reads the
same samples with it as without it, a regenerated shard gets a new cache file, what no shard names goes, a damaged
file is written again, a size is a cache of its own of resampled frames, and a shard without a checksum is held in
memory only. (MultiNet's moments from the cache at a size: tests/perception/test_moments.py.)"""
import shutil

import numpy as np
import pytest
import torch

from perception.datasets import FrameStream
from perception.frame_cache import FrameCache, prepare_cache, to_size
from perception.shards import Dataset, DatasetError, decode_image, image_column
from perception.train import train
from tests.perception.frames import dataset, tiny_config, workdir


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    copy = tmp_path_factory.mktemp("cache") / "frames"
    shutil.copytree(dataset(), copy)
    return Dataset(copy)


def test_a_cached_frame_is_the_stored_frame_decoded(data):
    cache = prepare_cache(data, data.shards, log=lambda *a: None)
    for shard in (data.shards[0], data.shards[-1]):
        frames = cache.frames(shard, "front")
        assert frames.shape == (shard.frames, 210, 280, 3) and frames.dtype == np.uint8
        stored = data.reader(shard).labels([image_column("front")]).column(image_column("front")).to_pylist()
        for step in (0, shard.frames // 2, shard.frames - 1):
            assert np.array_equal(frames[step], decode_image(stored[step]))


def test_the_stream_yields_the_same_samples_with_and_without_the_cache(data):
    cache = prepare_cache(data, data.select("train"), log=lambda *a: None)
    plain = FrameStream(data.root, "train", shuffle=True, seed=3, buffer=16)
    cached = FrameStream(data.root, "train", shuffle=True, seed=3, buffer=16, cache=cache)
    n = 0
    for (xa, ma, ya), (xb, mb, yb) in zip(plain, cached, strict=True):
        assert torch.equal(xa, xb) and torch.equal(ma, mb) and torch.equal(ya, yb)
        n += 1
    assert n == len(plain)


def test_training_with_the_cache_gives_the_same_model():
    a, b = workdir() / "cache-on.pt", workdir() / "cache-off.pt"
    train(tiny_config("mobilenet", a, cache=True), log=lambda *x: None)
    train(tiny_config("mobilenet", b, cache=False), log=lambda *x: None)
    sa, sb = torch.load(a, weights_only=True)["state_dict"], torch.load(b, weights_only=True)["state_dict"]
    assert all(torch.equal(sa[k], sb[k]) for k in sa)


def test_a_regenerated_shard_gets_a_new_file_and_the_old_one_goes(data):
    cache = prepare_cache(data, data.shards, log=lambda *a: None)
    shard = data.shards[0]
    old = cache.path(shard, "front")
    assert old.is_file()
    changed = type(shard)(shard.file, shard.episode, shard.frames, shard.split, shard.params, shard.size,
                          "f" * 64)
    assert cache.path(changed, "front") != old
    stray = cache.folder / "shard-999999.front.0123456789abcdef.npy"
    stray.write_bytes(b"x")
    assert FrameCache(data).prepare(data.shards) == 0     # everything cached already: nothing decoded again
    assert not stray.exists()                               # a file no shard names is removed


def test_a_damaged_file_is_written_again(data):
    cache = prepare_cache(data, data.shards, log=lambda *a: None)
    victim = cache.path(data.shards[1], "front")
    victim.write_bytes(victim.read_bytes()[:1000])                   # cut short
    assert cache.missing(data.shards) == [data.shards[1]]
    assert FrameCache(data).prepare(data.shards) == 1
    assert np.load(victim, mmap_mode="r").shape == (data.shards[1].frames, 210, 280, 3)


def test_a_size_is_a_cache_of_its_own_of_resampled_frames(data):
    full = prepare_cache(data, data.shards, log=lambda *a: None)
    small = FrameCache(data, size=(105, 140))
    assert small.folder == full.folder / "105x140"
    assert small.prepare(data.shards[:2]) == 2
    shard = data.shards[1]
    frames = small.frames(shard, "front")
    assert frames.shape == (shard.frames, 105, 140, 3)
    for step in (0, shard.frames - 1):
        assert np.array_equal(frames[step], to_size(np.asarray(full.frames(shard, "front")[step]), (105, 140)))
    assert full.prepare(data.shards) == 0 and small.path(shard, "front").is_file()   # neither removes the other's


def test_a_shard_without_a_checksum_is_not_cached_but_can_be_held_in_memory(data):
    shard = data.shards[0]
    bare = type(shard)(shard.file, shard.episode, shard.frames, shard.split, shard.params, shard.size, None)
    cache = FrameCache(data)
    with pytest.raises(DatasetError, match="SHA-256"):
        cache.missing([bare])
    cache.hold([bare])
    assert np.array_equal(cache.frames(bare, "front"), FrameCache(data).frames(shard, "front"))
