"""load_predictor: a frame in, the 14 indicators in canonical order out, as the closed loop's Driver wants."""
import numpy as np
import pytest

from perception.datasets import FrameDataset
from perception.predictor import load_predictor
from shm_bridge.worlds.highway import INDICATORS, label_set

from .frames import alexnet_checkpoint, dataset, gist15_checkpoint, gist_checkpoint


@pytest.fixture(scope="module")
def frame():
    image, _ = FrameDataset(dataset(), "test")[0]
    return image.permute(1, 2, 0).numpy()


def test_a_13_output_model_gives_14_indicators_with_fast_zero(frame):
    predict = load_predictor(alexnet_checkpoint()[0])
    out = predict(frame)
    assert out.shape == (14,) and out.dtype == np.float64
    assert out[INDICATORS.index("fast")] == 0.0
    assert predict.name == "alexnet" and predict.labels == label_set()
    assert np.all(np.isfinite(out))


def test_outputs_are_denormalised_indicators(frame):
    predict = load_predictor(gist_checkpoint()[0])
    out = predict(frame)
    # gaps in metres (not ~0.1..0.9), markings in metres with their signs
    assert out[INDICATORS.index("dist_MM")] > 5.0
    assert out[INDICATORS.index("toMarking_ML")] < 0 < out[INDICATORS.index("toMarking_MR")]


def test_lanes_left_is_dropped_from_the_14_and_fast_is_kept(frame):
    predict = load_predictor(gist15_checkpoint())
    out = predict(frame)
    everything = predict.labels_of(frame)
    assert out.shape == (14,) and predict.labels[-1] == "lanes_left"
    assert out[13] == pytest.approx(everything["fast"])
    assert set(everything) == set(INDICATORS) | {"lanes_left"}


def test_frames_of_another_size_are_resized(frame):
    import cv2

    predict = load_predictor(gist_checkpoint()[0])
    big = cv2.resize(frame, (560, 420), interpolation=cv2.INTER_NEAREST)
    np.testing.assert_allclose(predict(big), predict(frame), rtol=1e-3, atol=1e-3)


def test_bad_frames_are_refused():
    predict = load_predictor(gist_checkpoint()[0])
    with pytest.raises(ValueError, match="uint8 RGB"):
        predict(np.zeros((210, 280), dtype=np.uint8))
    with pytest.raises(ValueError, match="uint8 RGB"):
        predict(np.zeros((210, 280, 3), dtype=np.float32))


def test_the_closed_loop_driver_accepts_it(frame):
    from drivestudio.loop import Driver

    driver = Driver(perception=load_predictor(gist_checkpoint()[0]))
    action, estimate = driver.act(frame, np.zeros(14), speed=10.0, lanes=2)
    assert driver.name == "gist" and estimate.shape == (14,)
    assert -1.0 <= action.steer <= 1.0
