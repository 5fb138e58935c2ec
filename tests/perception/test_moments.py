"""MultiNet's data moments (perception/moments.py) from the frame cache at the network's 94 x 168: a cached moment
is the one the readers assemble from the shards, downsampled; the cache is written once per camera and read back
without decoding; a damaged cache file is built again; a folder that cannot be written holds them in memory."""

import shutil

import numpy as np
import pytest
import torch

from core import worlds
from perception.datasets import FrameDataset
from perception.frame_cache import FOLDER, FrameCache, to_size
from perception.models import Regressor, make_spec
from perception.moments import Moments

SIZE = (94, 168)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """Three full-size (336 x 188) episodes of 40 steps, one per behavioural mode."""
    out = tmp_path_factory.mktemp("cache") / "data"
    from tests.helpers import make
    make("generate", "--world", "sidewalk", "--frames", "120", "--episode-frames", "40", "--paths", "park",
         "--workers", "1", "--seed", "3", "--out", out)
    return out


def small(images: torch.Tensor) -> np.ndarray:
    """A reader's (12, 188, 336) moment at 94 x 168, each 3-channel image through the cache's resampling."""
    x = images.numpy()
    return np.concatenate([to_size(x[c:c + 3].transpose(1, 2, 0), SIZE).transpose(2, 0, 1)
                           for c in range(0, x.shape[0], 3)])


def test_a_cached_moment_equals_the_one_read_from_the_shards(data):
    moments = Moments([data], SIZE, log=lambda *a: None)
    reader = FrameDataset(data, None, normalised=False)
    assert len(moments) == len(reader) == 3 * (40 - 1 - 10)
    for i in (0, 1, 28, 29, 30, 57, len(reader) - 1):               # first, episode boundaries, last
        images, mode, target = reader[i]
        x, m, y = moments.batch([i])
        assert x.shape == (1, 12, 94, 168) and x.dtype == torch.uint8
        assert x.is_contiguous(memory_format=torch.channels_last)
        np.testing.assert_array_equal(x[0].numpy(), small(images))
        assert int(m[0]) == int(mode) and int(m[0]) == i // 29
        np.testing.assert_allclose(y[0].numpy(), target.numpy(), rtol=1e-6)


def test_the_cache_is_within_half_a_grey_level_of_the_networks_own_scaling(data):
    """At inference the predictor hands Z2Color full-size frames, which it averages 2x2 in float: the cached,
    rounded mean differs from that by at most half a grey level."""
    model = Regressor(make_spec("z2color", worlds.get("sidewalk")))
    moments = Moments([data], SIZE, log=lambda *a: None)
    images, _, _ = FrameDataset(data, None, normalised=False)[40]
    exact = model.scale_input(images[None])                          # x / 255 - 0.5 of the 2x2 mean
    cached = model.scale_input(moments.batch([40])[0])
    assert float((exact - cached).abs().max()) <= 0.5 / 255 + 1e-6


def test_the_cache_is_written_once_and_then_only_read(data, monkeypatch):
    Moments([data], SIZE, log=lambda *a: None)
    files = sorted((data / FOLDER / "94x168").glob("*.npy"))
    names = [[f"shard-00000{k}", camera] for k in range(3) for camera in ("left", "right")]
    assert [f.name.split(".")[:2] for f in files] == names
    assert all(np.load(f, mmap_mode="r").shape == (40, 94, 168, 3) for f in files)

    def no_decoding(*args):
        raise AssertionError("a cached shard was decoded again")

    monkeypatch.setattr(FrameCache, "decode", no_decoding)
    again = Moments([data], SIZE, log=lambda *a: None)
    assert all(isinstance(a, np.memmap) for cams in again.arrays for a in cams)


def test_a_damaged_cache_file_is_built_again(data):
    Moments([data], SIZE, log=lambda *a: None)
    victim = sorted((data / FOLDER / "94x168").glob("*.npy"))[2]
    victim.write_bytes(victim.read_bytes()[:1000])                   # cut short
    moments = Moments([data], SIZE, log=lambda *a: None)
    assert np.load(victim, mmap_mode="r").shape == (40, 94, 168, 3)
    images, _, _ = FrameDataset(data, None, normalised=False)[29]
    np.testing.assert_array_equal(moments.batch([29])[0][0].numpy(), small(images))


def test_a_dataset_folder_that_cannot_be_written_is_read_into_memory(data, monkeypatch, tmp_path):
    reference = Moments([data], SIZE, log=lambda *a: None)
    fresh = tmp_path / "data"
    shutil.copytree(data, fresh, ignore=shutil.ignore_patterns(FOLDER))

    def unwritable(self, *args):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(FrameCache, "prepare", unwritable)
    lines: list[str] = []
    moments = Moments([fresh], SIZE, log=lines.append)
    assert "reading them into memory" in lines[0]
    assert not any(isinstance(a, np.memmap) for cams in moments.arrays for a in cams)
    ids = np.arange(len(moments))
    assert torch.equal(moments.batch(ids)[0], reference.batch(ids)[0])


def test_validation_under_autocast_runs_in_bfloat16_within_a_percent_of_float32(data):
    """Validation's forward pass runs under the training's bfloat16 autocast when asked (amp): the loss moves by
    bfloat16's rounding only, and it does move (the autocast is in effect)."""
    from perception.multinet import evaluate_loss
    torch.manual_seed(0)
    model = Regressor(make_spec("z2color", worlds.get("sidewalk"))).to(memory_format=torch.channels_last)
    moments = Moments([data], SIZE, log=lambda *a: None)
    ids = np.arange(len(moments))
    exact = evaluate_loss(model, moments, ids, torch.device("cpu"))
    fast = evaluate_loss(model, moments, ids, torch.device("cpu"), amp=True)
    assert set(fast) == set(exact) and "val_loss_furtive" in fast
    assert fast["val_loss"] != exact["val_loss"]
    assert abs(fast["val_loss"] - exact["val_loss"]) <= 0.01 * exact["val_loss"]


@pytest.mark.parametrize("dtype", [torch.float32, torch.bfloat16], ids=str)
def test_moments_looked_up_as_gathered_are_the_scaled_images_bit_for_bit(data, dtype):
    """The training's batches (images looked up in the pixel table as they are gathered) hold exactly what
    scale_input then the cast make of the assembled images, channel for channel: instants and cameras in order."""
    from perception.multinet import scaled_images
    model = Regressor(make_spec("z2color", worlds.get("sidewalk")))
    moments = Moments([data], SIZE, log=lambda *a: None)
    ids = np.array([0, 28, 29, 57, len(moments) - 1, 5])
    table = model.pixel_table(dtype)
    got = moments.looked_up(ids, table)
    images = moments.images(ids)
    assert got.shape == images.shape and got.dtype == table.dtype
    np.testing.assert_array_equal(got, table[images])
    x = scaled_images(model, moments, ids, torch.device("cpu"), dtype)
    want = model.scale_input(torch.from_numpy(images).permute(0, 3, 1, 2).contiguous()).to(dtype)
    assert x.dtype == dtype and x.is_contiguous(memory_format=torch.channels_last)
    assert torch.equal(x.float(), want.float())
    assert not torch.equal(x[:, :3], x[:, 3:6])            # an instant's or a camera's image is not another's
