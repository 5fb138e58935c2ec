"""The SGD trainer's precision (perception/train_sgd.py, the setting amp): bfloat16 autocast where the CPU computes
bfloat16 natively, float32 with amp=false and where it does not; the checkpoint names the precision, and a run
continued in its own precision ends where the straight run ends."""
import pytest
import torch

from core.worlds.highway import HIGHWAY
from perception.checkpoint import load_checkpoint
from perception.mobilenet import Float32Conv
from perception.models import build
from perception.precision import bf16_native
from perception.train import train
from tests.perception.frames import tiny_config, workdir

NATIVE = bf16_native(torch.device("cpu"))
EMULATED = "this CPU has neither AVX512-BF16 nor AMX: the trainer trains in float32 here, bfloat16 is not used"


def quiet(*_a, **_k) -> None:
    pass


def weights_equal(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.skipif(not NATIVE, reason=EMULATED)
def test_a_cpu_with_native_bfloat16_trains_under_bfloat16_autocast_and_lowers_the_loss():
    path = workdir() / "mobilenet-bf16.pt"
    lines: list[str] = []
    train(tiny_config("mobilenet", path, iterations=12, val_every=12, log_every=4, lr=3e-3), log=lines.append)
    ckpt = load_checkpoint(path)
    assert ckpt["train"]["precision"] == "bfloat16"
    assert any("bfloat16 autocast" in line for line in lines)
    history = ckpt["train"]["history"]
    assert history[-1]["train_loss"] < 0.8 * history[0]["train_loss"]
    # the master weights (and the moving average the checkpoint uses) stay float32
    for weights in (ckpt["state_dict"], ckpt["training_state_dict"]):
        assert {v.dtype for v in weights.values() if v.is_floating_point()} == {torch.float32}


def test_amp_false_and_a_cpu_without_native_bfloat16_train_in_float32_alike(monkeypatch):
    plain = workdir() / "mobilenet-amp-false.pt"
    train(tiny_config("mobilenet", plain, iterations=4, amp=False), log=quiet)
    monkeypatch.setattr("perception.train_sgd.bf16_native", lambda device: False)
    emulated = workdir() / "mobilenet-emulated.pt"
    lines: list[str] = []
    train(tiny_config("mobilenet", emulated, iterations=4), log=lines.append)
    a, b = load_checkpoint(plain), load_checkpoint(emulated)
    assert a["train"]["precision"] == b["train"]["precision"] == "float32"
    assert any("bfloat16 is not native" in line for line in lines)
    assert not any("autocast" in line for line in lines)
    assert weights_equal(a["state_dict"], b["state_dict"])


@pytest.mark.skipif(not NATIVE, reason=EMULATED)
def test_a_bfloat16_training_continued_ends_where_the_straight_run_ends():
    straight, resumed = workdir() / "bf16-straight.pt", workdir() / "bf16-resumed.pt"
    train(tiny_config("mobilenet", straight, iterations=8), log=quiet)
    train(tiny_config("mobilenet", resumed, iterations=4), log=quiet)
    train(tiny_config("mobilenet", resumed, iterations=8), log=quiet)
    a, b = load_checkpoint(straight), load_checkpoint(resumed)
    assert b["train"]["iteration"] == 8 and b["train"]["precision"] == "bfloat16"
    assert weights_equal(a["state_dict"], b["state_dict"])
    assert weights_equal(a["training_state_dict"], b["training_state_dict"])
    # continued in another precision, it says that the weights part from the uninterrupted run's
    lines: list[str] = []
    train(tiny_config("mobilenet", resumed, iterations=10, amp=False), log=lines.append)
    assert any("was trained in bfloat16, this run trains in float32" in line for line in lines)
    assert load_checkpoint(resumed)["train"]["precision"] == "float32"


def test_the_strided_depthwise_convolutions_compute_in_float32_under_autocast():
    model = build("mobilenet", HIGHWAY)
    strided = [m for m in model.modules() if isinstance(m, Float32Conv)]
    assert len(strided) == 3 and all(m.stride == (2, 2) and m.groups == m.in_channels for m in strided)
    conv = strided[0]
    x = torch.randn(2, conv.in_channels, 27, 35)
    plain = torch.nn.functional.conv2d(x, conv.weight, conv.bias, conv.stride, conv.padding, groups=conv.groups)
    assert torch.equal(conv(x), plain)                     # without autocast: the nn.Conv2d it replaced
    with torch.autocast("cpu", dtype=torch.bfloat16):
        y = conv(x.bfloat16())
    assert y.dtype == torch.float32
    torch.testing.assert_close(y, torch.nn.functional.conv2d(x.bfloat16().float(), conv.weight, conv.bias,
                                                             conv.stride, conv.padding, groups=conv.groups))
