"""Z2Color and MultiNet's training measures, rule by rule (Chowdhuri, Pankaj and Zipser, MultiNet, 2017)."""
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from core import worlds
from perception.models import Regressor, make_spec
from perception.multinet import (
    STEERING,
    balanced_batches,
    steering_moments,
    summarise_trials,
    t95,
    train_loss,
    validation_loss,
)
from perception.z2color import Z2Color

SIDEWALK = worlds.get("sidewalk")


def test_z2color_layers_and_size():
    net = Z2Color()
    x = torch.zeros(2, 12, 94, 168)
    after_conv1 = net.conv1(x)
    assert after_conv1.shape == (2, 96, 13, 26)                       # conv1 11x11/3, max-pool 3/2
    assert net.conv2[0].in_channels == 99                             # 96 + the 3 mode planes
    assert net.conv2(torch.zeros(2, 99, 13, 26)).shape == (2, 256, 2, 5)
    assert net.fc[1].in_features == 2560 and net.fc[-1].out_features == 20
    params = sum(p.numel() for p in net.parameters())
    assert params <= 1_700_000 and params == 1_690_036
    assert isinstance(net.conv1[3], torch.nn.BatchNorm2d) and isinstance(net.conv2[3], torch.nn.BatchNorm2d)
    mtl = Z2Color(modal=False)
    assert mtl.conv2[0].in_channels == 96 and sum(p.numel() for p in mtl.parameters()) < params
    assert 3 * sum(p.numel() for p in mtl.parameters()) > params      # one MultiNet is smaller than three MTL nets


def test_the_mode_is_a_binary_tensor_of_three_planes_of_13_by_26():
    net = Z2Color()
    planes = net.mode_planes(torch.tensor([0, 2, -1]), 13, 26)
    assert planes.shape == (3, 3, 13, 26)
    assert planes[0, 0].eq(1).all() and planes[0, 1:].eq(0).all()    # direct: all ones in plane 0
    assert planes[1, 2].eq(1).all() and planes[1, :2].eq(0).all()    # furtive: plane 2
    assert planes[2].eq(0).all()                                      # no mode: all zeros


def test_changing_only_the_mode_changes_the_output():
    torch.manual_seed(0)
    model = Regressor(make_spec("z2color", SIDEWALK)).eval()
    images = torch.randint(0, 256, (1, 12, 94, 168), dtype=torch.uint8).expand(3, -1, -1, -1)
    with torch.no_grad():
        out = model(images, torch.tensor([0, 1, 2]))
    assert out.shape == (3, 20)
    assert not torch.allclose(out[0], out[1]) and not torch.allclose(out[1], out[2])
    mtl = Regressor(make_spec("z2color", SIDEWALK, modal=False, mtl="direct")).eval()
    with torch.no_grad():
        same = mtl(images, torch.tensor([0, 1, 2]))
    torch.testing.assert_close(same[0], same[2])                      # the MTL net has no modal input


def test_inputs_are_scaled_x_over_255_minus_half_and_averaged_down_2x2():
    model = Regressor(make_spec("z2color", SIDEWALK))
    big = torch.zeros(1, 12, 188, 336, dtype=torch.uint8)
    big[..., 0::2, 0::2] = 255                                         # one bright pixel in each 2x2 block
    x = model.scale_input(big)
    assert x.shape == (1, 12, 94, 168)
    torch.testing.assert_close(x, torch.full_like(x, 255 / 4 / 255 - 0.5))


def test_training_loss_is_equation_1():
    n = 10
    pred = torch.zeros(2, 2 * n)
    target = torch.zeros(2, 2 * n)
    target[0, 3] = 1.0       # a steering error of 1 at step 4
    target[1, n + 9] = 2.0   # a motor error of 2 at step 10
    # 1/(2n) sum_t (s' - s)^2 + (m' - m)^2, averaged over the two moments
    expected = ((1.0 ** 2) / (2 * n) + (2.0 ** 2) / (2 * n)) / 2
    assert float(train_loss(pred, target)) == pytest.approx(expected)


def test_validation_loss_is_equation_2_on_the_last_step_only():
    n = 10
    pred = torch.zeros(1, 2 * n)
    target = torch.zeros(1, 2 * n)
    target[0, :n - 1] = 5.0           # errors on steps 1..9 do not count
    target[0, n:2 * n - 1] = 5.0
    assert float(validation_loss(pred, target)[0]) == 0.0
    target[0, n - 1], target[0, 2 * n - 1] = 0.3, 0.4   # steer+10 and motor+10: indices 9 and 19
    assert float(validation_loss(pred, target)[0]) == pytest.approx((0.3 ** 2 + 0.4 ** 2) / 2)


def test_batches_hold_the_modes_equally():
    train = {0: np.arange(0, 100), 1: np.arange(100, 130), 2: np.arange(130, 400)}
    rng = np.random.default_rng(0)
    seen = set()
    for ids in balanced_batches(train, 120, rng, 20):
        assert len(ids) == 120
        counts = [np.sum((ids >= lo) & (ids < hi)) for lo, hi in ((0, 100), (100, 130), (130, 400))]
        assert counts == [40, 40, 40]
        seen.update(ids.tolist())
    assert set(range(100, 130)) <= seen          # the small mode's moments all come round


def test_a_steer_share_draws_that_share_of_each_mode_from_its_steering_moments():
    train = {0: np.arange(0, 100), 1: np.arange(100, 130), 2: np.arange(130, 400)}
    steering = {0: np.arange(0, 10), 1: np.arange(100, 102), 2: np.arange(390, 400)}
    for ids in balanced_batches(train, 120, np.random.default_rng(0), 20, steering, 0.5):
        for m, (lo, hi) in enumerate(((0, 100), (100, 130), (130, 400))):
            mine = ids[(ids >= lo) & (ids < hi)]
            assert len(mine) == 40                                   # the modes stay equal
            assert np.isin(mine, steering[m]).sum() >= 20            # half of them (at least) steering moments
    plain = list(balanced_batches(train, 120, np.random.default_rng(1), 5))
    shared = list(balanced_batches(train, 120, np.random.default_rng(1), 5, steering, 0.0))
    assert all(np.array_equal(a, b) for a, b in zip(plain, shared))   # share 0: the draws as they always were


def test_a_steering_moment_is_one_whose_actuated_steering_is_off_straight_ahead():
    class Fake:
        targets = np.full((4, 20), 0.5, dtype=np.float32)
    Fake.targets[0, 9] = 0.5 + STEERING           # steer+10 at the bound: steering
    Fake.targets[1, 9] = 0.5 - STEERING - 0.01    # the other way
    Fake.targets[2, 0] = 0.9                      # steer+1 far off, the actuated steer+10 straight: not steering
    Fake.targets[3, 19] = 0.9                     # motor+10: not steering
    outputs = [f"steer+{k}" for k in range(1, 11)] + [f"motor+{k}" for k in range(1, 11)]
    got = steering_moments(Fake(), {0: np.arange(4)}, outputs)
    assert got[0].tolist() == [0, 1]


def test_confidence_intervals_over_trials():
    history = [{"trial": k, "epoch": 1, "val_loss": v} for k, v in enumerate([1.0, 2.0, 3.0], 1)]
    row = summarise_trials(history, ["val_loss"])[0]
    assert row["val_loss_mean"] == pytest.approx(2.0) and row["trials"] == 3
    assert row["val_loss_ci95"] == pytest.approx(4.303 * 1.0 / np.sqrt(3), rel=1e-3)   # t(2) * s / sqrt(n)
    assert t95(7) == pytest.approx(2.365)


def test_the_driver_actuates_the_tenth_output_smoothed(tmp_path):
    """The 10th steering and motor outputs (330 ms ahead) are actuated, as (x + previous) / 2, in the mode the
    bridge's flag says."""
    from drivestudio.drivers import DirectDriver

    class Fake:
        name, description = "z2color", "fake"
        outputs = SIDEWALK.estimate_names
        instants, modes = (-1, 0), SIDEWALK.modes

        def __init__(self):
            self.calls = []

        def __call__(self, images, mode=None):
            self.calls.append((len(images), mode))
            out = np.zeros(20)
            out[9], out[19] = 0.9, 0.7        # steer+10, motor+10
            out[0], out[10] = 0.1, 0.1        # steer+1, motor+1: side tasks, never actuated
            return out

    fake = Fake()
    driver = DirectDriver(fake, SIDEWALK, smooth=True)
    frames = (np.zeros((4, 4, 3), np.uint8), np.zeros((4, 4, 3), np.uint8))
    percept = SimpleNamespace(frames=frames, record=np.zeros(len(SIDEWALK.truth)), t=0.0, behaviour=2)
    first, estimate = driver.act(percept)
    np.testing.assert_allclose(first, [0.9, 0.7])                    # nothing to average with yet
    driver.predictor.__call__ = None
    fake_values = iter([0.5, 0.3])
    fake.__class__.__call__ = lambda self, images, mode=None: np.r_[np.zeros(9), next(fake_values), np.zeros(9),
                                                                   next(fake_values)]
    second, _ = driver.act(percept)
    np.testing.assert_allclose(second, [(0.5 + 0.9) / 2, (0.3 + 0.7) / 2])
    assert estimate.shape == (20,) and estimate[9] == pytest.approx(0.9)
    assert fake.calls[0] == (4, "furtive")                            # 4 images: left/right at t-1 and t


def test_export_round_trip(tmp_path):
    pytest.importorskip("onnxruntime")
    from perception.checkpoint import save_checkpoint
    from perception.export import export_onnx

    torch.manual_seed(1)
    model = Regressor(make_spec("z2color", SIDEWALK)).eval()
    save_checkpoint(tmp_path / "m.pt", {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    r = export_onnx(tmp_path / "m.pt", tmp_path / "m.onnx")
    assert r["max_abs_difference"] < 1e-4 and r["parameters"] == 1_690_036
    assert r["float32_mb"] == pytest.approx(6.76, abs=0.01) and (tmp_path / "m.onnx").stat().st_size > 6_000_000
    import onnxruntime as ort
    sess = ort.InferenceSession(str(tmp_path / "m.onnx"), providers=["CPUExecutionProvider"])
    images = np.random.default_rng(0).integers(0, 256, (2, 12, 94, 168), dtype=np.uint8)
    out = sess.run(["outputs"], {"images": images, "modes": np.array([0, 2])})[0]
    with torch.no_grad():
        ref = model.denormalise(model(torch.from_numpy(images), torch.tensor([0, 2])))
    np.testing.assert_allclose(out, ref, atol=1e-4)


def test_a_finished_multinet_is_not_handed_back_as_an_mtl_net(tmp_path):
    """train --set mtl=direct --out over a finished MultiNet is refused, not answered 'trained already'."""
    import pytest as _pytest
    import torch as _torch

    from core import worlds as _worlds
    from perception.checkpoint import CheckpointError, save_checkpoint
    from perception.models import Regressor, make_spec
    from perception.train import train
    from perception.training import TrainConfig
    model = Regressor(make_spec("z2color", _worlds.get("sidewalk"), modal=True))
    out = tmp_path / "multinet.pt"
    save_checkpoint(out, {"spec": model.spec, "state_dict": model.state_dict(), "train": {"trials": 1}})
    _torch.manual_seed(0)
    with _pytest.raises(CheckpointError, match="is a finished MultiNet, not the MTL net of mode direct"):
        train(TrainConfig(data=str(tmp_path), model="z2color", out=str(out), mtl="direct"), log=lambda *a: None)


@pytest.mark.parametrize("avx512_bf16, amx, native", [(False, False, False), (True, False, True), (False, True, True)])
def test_bfloat16_autocast_only_where_the_cpu_computes_it_natively(monkeypatch, avx512_bf16, amx, native):
    """Emulated bfloat16 trained Z2Color 6.8x slower than float32 on an AVX2-only CPU: the default autocast is for
    CPUs with AVX512-BF16 or AMX only (perception/precision.py's bf16_native)."""
    from perception.precision import bf16_native
    monkeypatch.setattr(torch.cpu, "_is_avx512_bf16_supported", lambda: avx512_bf16, raising=False)
    monkeypatch.setattr(torch.cpu, "_is_amx_tile_supported", lambda: amx, raising=False)
    assert bf16_native(torch.device("cpu")) is native
