"""perception/optimizers.py: the trainers' optimisers use PyTorch's fused (or multi-tensor) kernels, and those
compute the same update as the plain implementation the project trained with before."""
import pytest
import torch

from perception.optimizers import OPTIMIZERS, make_optimizer

REFERENCE = {"sgd": lambda ps: torch.optim.SGD(ps, lr=0.01, momentum=0.9, weight_decay=1e-4, foreach=False),
             "adam": lambda ps: torch.optim.Adam(ps, lr=0.01, weight_decay=1e-4, foreach=False),
             "adadelta": lambda ps: torch.optim.Adadelta(ps, lr=0.01, weight_decay=1e-4, foreach=False)}


def trained(opt_for, steps: int = 5) -> list[torch.Tensor]:
    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Conv2d(3, 4, 3), torch.nn.Flatten(), torch.nn.Linear(4 * 6 * 6, 2))
    opt = opt_for(list(net.parameters()))
    x, y = torch.randn(8, 3, 8, 8), torch.randn(8, 2)
    for _ in range(steps):
        opt.zero_grad()
        torch.nn.functional.mse_loss(net(x), y).backward()
        opt.step()
    return [p.detach().clone() for p in net.parameters()]


@pytest.mark.parametrize("name", OPTIMIZERS)
def test_the_fast_optimiser_computes_the_plain_update(name):
    fast = trained(lambda ps: make_optimizer(name, ps, 0.01, 0.9, 1e-4))
    plain = trained(REFERENCE[name])
    start = trained(REFERENCE[name], steps=0)
    assert any(not torch.equal(a, b) for a, b in zip(fast, start))          # it did train
    for a, b in zip(fast, plain):
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-6)


def test_adam_and_sgd_are_fused_on_the_cpu_and_adadelta_multi_tensor():
    ps = [torch.nn.Parameter(torch.zeros(3))]
    assert make_optimizer("adam", ps, 1e-3).defaults["fused"] is True
    assert make_optimizer("sgd", ps, 1e-3).defaults["fused"] is True
    assert make_optimizer("adadelta", ps, 1.0).defaults["foreach"] is True


def test_an_unknown_optimiser_is_refused_by_name():
    with pytest.raises(ValueError, match="unknown optimizer 'rmsprop'"):
        make_optimizer("rmsprop", [torch.nn.Parameter(torch.zeros(1))], 1e-3)
