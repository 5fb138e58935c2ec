"""load_predictor: a sample's images in, the model's outputs (denormalised, named) out; the highway's Chen driver puts
them into the 14 indicators in canonical order."""
import numpy as np
import pytest

from core.worlds.highway import HIGHWAY, INDICATORS, label_set
from perception.datasets import FrameDataset
from perception.predictor import load_predictor
from tests.perception.frames import alexnet_checkpoint, dataset, gist15_checkpoint, gist_checkpoint


@pytest.fixture(scope="module")
def frame():
    image, _, _ = FrameDataset(dataset(), "test")[0]
    return image.permute(1, 2, 0).numpy()


def _percept(frame, speed=10.0, lanes=2):
    from types import SimpleNamespace
    record = HIGHWAY.pack({n: 0.0 for n in HIGHWAY.truth_names})
    record[HIGHWAY.index("speed")], record[HIGHWAY.index("lanes")] = speed, lanes
    return SimpleNamespace(frames=(frame,), record=record, t=0.0)


def test_a_13_output_model_gives_13_named_outputs(frame):
    predict = load_predictor(alexnet_checkpoint()[0])
    out = predict(frame)
    assert out.shape == (13,) and out.dtype == np.float64 and np.all(np.isfinite(out))
    assert predict.name == "alexnet" and predict.labels == label_set() == predict.outputs
    assert predict.world == "highway" and predict.instants == (0,) and predict.cameras == ("front",)


def test_outputs_are_denormalised_indicators(frame):
    predict = load_predictor(gist_checkpoint()[0])
    out = predict.named(frame)
    # gaps in metres (not ~0.1..0.9), markings in metres with their signs
    assert out["dist_MM"] > 5.0
    assert out["toMarking_ML"] < 0 < out["toMarking_MR"]


def test_the_chen_driver_places_outputs_into_the_estimate_record(frame):
    from drivestudio.worlds.highway.drivers import ChenDriver
    predict = load_predictor(gist15_checkpoint())
    everything = predict.named(frame)
    assert set(everything) == set(INDICATORS) | {"lanes_left"}
    action, estimate = ChenDriver(predict).act(_percept(frame))
    # the highway's estimate record: 14 indicators, lanes_left, then the four rear labels (NaN: not predicted)
    assert estimate.shape == (19,)
    assert np.isnan(estimate[15:]).all()
    assert estimate[13] == pytest.approx(everything["fast"]) and estimate[14] == pytest.approx(everything["lanes_left"])
    _, estimate13 = ChenDriver(load_predictor(gist_checkpoint()[0])).act(_percept(frame))
    assert np.isnan(estimate13[13:]).all() and np.isfinite(estimate13[:13]).all()


def test_frames_of_another_size_are_resized(frame):
    import cv2

    predict = load_predictor(gist_checkpoint()[0])
    big = cv2.resize(frame, (560, 420), interpolation=cv2.INTER_NEAREST)
    np.testing.assert_allclose(predict(big), predict(frame), rtol=1e-3, atol=1e-3)


def test_bad_frames_are_refused():
    predict = load_predictor(gist_checkpoint()[0])
    with pytest.raises(ValueError, match="uint8 images"):
        predict(np.zeros((210, 280), dtype=np.uint8))
    with pytest.raises(ValueError, match="uint8 images"):
        predict(np.zeros((210, 280, 3), dtype=np.float32))
    with pytest.raises(ValueError, match="reads 3 channels"):
        predict([np.zeros((210, 280, 3), np.uint8)] * 2)


def test_the_closed_loop_driver_accepts_it(frame):
    from drivestudio.worlds.highway.drivers import ChenDriver

    driver = ChenDriver(load_predictor(gist_checkpoint()[0]))
    action, estimate = driver.act(_percept(frame))
    assert driver.name == "gist" and estimate.shape == (19,)   # 14 indicators, lanes_left, 4 rear labels
    assert action.shape == (3,) and -1.0 <= action[0] <= 1.0


def test_a_checkpoint_of_another_world_is_refused():
    from perception.checkpoint import CheckpointError
    with pytest.raises(CheckpointError, match="a model of the highway world, not of the sidewalk world"):
        load_predictor(gist_checkpoint()[0], world="sidewalk")


@pytest.mark.parametrize("native", [True, False], ids=["bf16-native", "bf16-emulated"])
def test_z2color_predicts_under_bfloat16_only_where_native_and_close_to_float32(monkeypatch, native):
    """Z2Color's predictor computes under bfloat16 autocast where the CPU has it natively (as its trainer does),
    within a few thousandths of float32's outputs; elsewhere, and for the highway's families, in float32, bit for bit
    the model's own forward pass."""
    import torch

    from core.worlds.highway import HIGHWAY
    from core.worlds.sidewalk import SIDEWALK
    from perception.models import build
    from perception.predictor import Predictor
    monkeypatch.setattr("perception.predictor.bf16_native", lambda device: native)
    torch.manual_seed(0)
    net = build("z2color", SIDEWALK).eval()
    rng = np.random.default_rng(0)
    images = [rng.integers(0, 256, (94, 168, 3), dtype=np.uint8) for _ in range(4)]
    driving, exact = Predictor(net, net.spec), Predictor(net, net.spec, amp=False)
    assert driving.amp is native and exact.amp is False
    with torch.inference_mode():
        own = net.denormalise(net(exact._batch([images]), torch.tensor([0])))[0]
    np.testing.assert_array_equal(exact(images, "direct"), own)
    got = driving(images, "direct")
    spread = np.abs(own).max()
    assert spread > 0.01
    if native:
        assert not np.array_equal(got, own)                   # computed otherwise...
        np.testing.assert_allclose(got, own, atol=0.02 * spread)      # ...to nearly the same outputs
    else:
        np.testing.assert_array_equal(got, own)
    alexnet = build("alexnet", HIGHWAY)
    assert Predictor(alexnet, alexnet.spec).amp is False
