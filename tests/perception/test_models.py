"""Each model family maps a batch of 210x280 frames to 13, 14 or 15 outputs; GIST descriptors are 512 numbers
that depend on the frame only."""
import pytest
import torch

from core.worlds.highway import HIGHWAY, label_set
from perception.gist import GistDescriptor, gabor_bank
from perception.models import IMAGENET_MEAN, build, describe, make_spec

LABEL_SETS = [label_set(), label_set(fast=True), label_set(fast=True, lanes_left=True)]


@pytest.fixture(scope="module")
def frames():
    g = torch.Generator().manual_seed(0)
    return torch.randint(0, 256, (2, 3, 210, 280), dtype=torch.uint8, generator=g)


@pytest.mark.parametrize("labels", LABEL_SETS, ids=lambda names: f"{len(names)}")
def test_alexnet_outputs_one_value_per_label(frames, labels):
    with torch.no_grad():
        assert build("alexnet", HIGHWAY, labels)(frames).shape == (2, len(labels))


@pytest.mark.parametrize("labels", LABEL_SETS, ids=lambda names: f"{len(names)}")
def test_gist_outputs_one_value_per_label(frames, labels):
    with torch.no_grad():
        assert build("gist", HIGHWAY, labels)(frames).shape == (2, len(labels))


def test_alexnet_is_five_convs_then_4096_4096_256_n_without_dropout_or_sigmoid():
    net = build("alexnet", HIGHWAY, label_set()).net
    convs = [m for m in net.features if isinstance(m, torch.nn.Conv2d)]
    linears = [m for m in net.regressor if isinstance(m, torch.nn.Linear)]
    assert len(convs) == 5
    assert [m.out_features for m in linears] == [4096, 4096, 256, 13]
    kinds = {type(m) for m in net.modules()}
    assert torch.nn.Dropout not in kinds and torch.nn.Sigmoid not in kinds


@pytest.mark.parametrize("labels", LABEL_SETS, ids=lambda names: f"{len(names)}")
def test_vgg16_frozen_outputs_one_value_per_label_and_trains_only_the_head(frames, labels):
    model = build("vgg16", HIGHWAY, labels, frozen=True, batch_norm=False)
    head = [m for m in model.net.regressor if isinstance(m, torch.nn.Linear)]
    assert [m.out_features for m in head] == [4096, 256, len(labels)]
    assert not any(p.requires_grad for p in model.net.features.parameters())
    model.train()
    out = model(frames)
    assert out.shape == (2, len(labels))
    out.square().sum().backward()
    assert all(p.grad is not None for p in model.net.regressor.parameters())
    assert all(p.grad is None for p in model.net.features.parameters())


def test_vgg16_unfrozen_with_batch_norm_trains_everything(frames):
    model = build("vgg16", HIGHWAY, label_set(), frozen=False, batch_norm=True, mean=IMAGENET_MEAN)
    assert any(isinstance(m, torch.nn.BatchNorm2d) for m in model.net.features)
    assert all(p.requires_grad for p in model.parameters())
    model.train()
    model(frames[:1]).square().sum().backward()
    assert model.net.features[0].weight.grad is not None
    assert "VGG-16-BN (all layers trained" in describe(model.spec)


def test_input_handling_is_part_of_the_model(frames):
    spec = make_spec("alexnet", HIGHWAY, label_set(), mean=(0.4, 0.5, 0.6), std=(0.2, 0.2, 0.2))
    model = build("alexnet", HIGHWAY, label_set(), mean=(0.4, 0.5, 0.6), std=(0.2, 0.2, 0.2)).eval()
    assert spec["input"] == {"channels": 3, "height": 210, "width": 280, "instants": [0], "cameras": ["front"],
                             "modes": [], "scaling": "standardise", "mean": [0.4, 0.5, 0.6], "std": [0.2, 0.2, 0.2]}
    assert spec["world"] == "highway" and spec["outputs"] == spec["labels"] == list(label_set())
    with torch.no_grad():
        a = model(frames)
        b = model(frames.float() / 255.0)  # float frames are taken as already in [0, 1]
    torch.testing.assert_close(a, b)
    assert "mean" in dict(model.named_buffers()) and "std" in dict(model.named_buffers())


def test_gist_descriptor_is_4_scales_by_8_orientations_by_4x4_cells(frames):
    d = GistDescriptor()
    assert d.gabor.shape[0] == 32 and d.dim == 512
    f = d(frames.float() / 255)
    assert f.shape == (2, 512)
    assert torch.isfinite(f).all() and (f >= 0).all()


def test_gist_descriptor_is_deterministic_and_depends_on_the_frame(frames):
    a = GistDescriptor()(frames.float() / 255)
    b = GistDescriptor()(frames.float() / 255)
    torch.testing.assert_close(a, b)
    assert not torch.allclose(a[0], a[1])


def test_gist_energies_are_the_cell_means_of_each_filters_response_magnitude(frames):
    """LMgist's energies written out: |ifft2(fft2(prefiltered frame) x filter)|, the padding cut off, averaged over
    the 4x4 cells, filter by filter; the same whichever frames are computed together."""
    d = GistDescriptor()
    x = torch.cat([frames, frames.flip(3)]).float() / 255
    grey, b = d.grey(x), d.boundary
    response = torch.fft.ifft2(torch.fft.fft2(d.prefilter(grey))[:, None] * d.gabor[None]).abs()[..., b:-b, b:-b]
    h, w = response.shape[-2] // 4, response.shape[-1] // 4
    cells = response.reshape(len(x), 32, 4, h, 4, w).mean((3, 5)).flatten(1)
    for chunk in (1, 2, 16):
        torch.testing.assert_close(d(x, chunk=chunk), cells, rtol=1e-5, atol=1e-7)


def test_gabor_filters_peak_at_their_scale_frequency():
    bank = gabor_bank(64, 64)
    assert bank.shape == (32, 64, 64)
    assert float(bank.max()) == pytest.approx(1.0, abs=0.05)
    # the finest scale responds at 0.3 cycles/pixel, the coarsest at 0.3 / 1.85^3
    fine, coarse = bank[0], bank[24]
    fx = torch.fft.fftfreq(64)
    assert abs(float(fx[fine[0].argmax()]) - 0.3) < 0.02
    assert abs(float(fx[coarse[0].argmax()]) - 0.3 / 1.85 ** 3) < 0.02


def test_a_family_is_imported_alone_and_the_others_still_on_demand():
    """Building Z2Color must not import torchvision (a second of every sidewalk command's start-up); asking for
    AlexNet afterwards still finds it, and the list of families is complete."""
    import subprocess
    import sys
    code = ("import sys\n"
            "from core.worlds.sidewalk import SIDEWALK\n"
            "from perception.models import build, families, family\n"
            "build('z2color', SIDEWALK)\n"
            "assert 'torchvision' not in sys.modules, 'torchvision imported for Z2Color'\n"
            "assert family('alexnet').name == 'alexnet' and 'torchvision' in sys.modules\n"
            "assert {'alexnet', 'vgg16', 'gist', 'z2color', 'mobilenet'} <= set(families())\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr


@pytest.mark.parametrize("dtype", [torch.float32, torch.bfloat16], ids=str)
def test_scale_pixels_is_scale_input_bit_for_bit(dtype):
    """The trainer's table lookup gives exactly what scale_input then a cast gives, for every pixel value, in
    channels-last memory; it declines pixels that need resampling and a scaling that differs per channel."""
    import numpy as np

    from core.worlds.sidewalk import SIDEWALK
    net = build("z2color", SIDEWALK)
    h, w = net.size
    rng = np.random.default_rng(0)
    pixels = rng.integers(0, 256, (3, h, w, 12), dtype=np.uint8)
    pixels.reshape(-1)[:256] = np.arange(256)                            # every value at least once
    got = net.scale_pixels(pixels, dtype)
    want = net.scale_input(torch.from_numpy(pixels).permute(0, 3, 1, 2)).to(dtype)
    assert got.dtype == dtype and got.shape == want.shape
    assert torch.equal(got.view(torch.int16) if dtype == torch.bfloat16 else got,
                       want.view(torch.int16) if dtype == torch.bfloat16 else want)
    assert got.is_contiguous(memory_format=torch.channels_last)
    assert net.scale_pixels(rng.integers(0, 256, (1, 2 * h, 2 * w, 12), dtype=np.uint8), dtype) is None
    assert build("alexnet", HIGHWAY, LABEL_SETS[0]).scale_pixels(
        rng.integers(0, 256, (1, 210, 280, 3), dtype=np.uint8), dtype) is None


@pytest.mark.parametrize("factor", [2, 3])
@pytest.mark.parametrize("channels_last", [False, True], ids=["nchw", "channels-last"])
def test_block_mean_of_uint8_frames_is_the_area_mean_of_their_floats_bit_for_bit(factor, channels_last):
    """The 16-bit integer sums of uint8 frames give exactly the block means of the same frames as floats, in
    either memory layout, which are area resampling's, and the block of every output pixel is its own."""
    import torch.nn.functional as F

    from perception.models import _block_mean
    g = torch.Generator().manual_seed(factor)
    frames = torch.randint(0, 256, (2, 6, 7 * factor, 5 * factor), dtype=torch.uint8, generator=g)
    if channels_last:
        frames = frames.contiguous(memory_format=torch.channels_last)
    got = _block_mean(frames, factor, factor)
    assert got.dtype == torch.float32 and got.shape == (2, 6, 7, 5)
    area = F.interpolate(frames.float(), size=(7, 5), mode="area")
    if factor == 2:           # a division by 4 is exact, as the sums are: area resampling's result bit for bit
        assert torch.equal(got, area)
    torch.testing.assert_close(got, area)
    assert torch.equal(got, _block_mean(frames.float(), factor, factor))
    for i, j in ((0, 0), (0, 1), (2, 3)):       # each output pixel is the mean of its own block
        assert got[0, 1, i, j] == frames[0, 1, i * factor:(i + 1) * factor, j * factor:(j + 1) * factor].float().mean()
