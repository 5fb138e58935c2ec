"""The ensemble (perception/ensemble.py, made by drivestudio/ensemble.py): every member reads the frame with its own
input statistics, the closest gap any member reads is believed, every other output is the members' mean, each
output over the members that estimate it; members that read something else are refused in one line, exit status 2,
nothing written."""

import numpy as np
import pytest
import torch

from core.worlds.highway import HIGHWAY
from drivestudio.ensemble import make
from perception.checkpoint import CheckpointError, save_checkpoint
from perception.models import build, describe, load_model
from perception.predictor import load_predictor

FRAMES = torch.randint(0, 256, (3, 3, 210, 280), dtype=torch.uint8, generator=torch.Generator().manual_seed(0))


def member(path, seed: int, mean: float, std: float, instants=(0,), **kwargs):
    """A randomly initialised MobileNet with its own input statistics, saved as a checkpoint."""
    torch.manual_seed(seed)
    c = 3 * len(instants)
    model = build("mobilenet", HIGHWAY, mean=[mean] * c, std=[std] * c, instants=instants, **kwargs)
    with torch.no_grad():   # outputs spread over the normalised range, so that min and mean differ clearly
        for p in model.parameters():
            p.add_(torch.randn_like(p) * 0.05)
    save_checkpoint(path, {"spec": model.spec, "state_dict": model.state_dict()})
    return path


@pytest.fixture(scope="module")
def members(tmp_path_factory):
    d = tmp_path_factory.mktemp("ensemble")
    return [member(d / "a.pt", 1, 0.3, 0.2), member(d / "b.pt", 2, 0.6, 0.25)]


def estimates(path) -> np.ndarray:
    net, _ = load_model(path)
    with torch.no_grad():
        return net.denormalise(net(FRAMES))


def test_the_closest_gap_and_the_mean_of_everything_else(members, tmp_path):
    out = tmp_path / "ens.pt"
    save_checkpoint(out, make([str(p) for p in members]))
    a, b = estimates(members[0]), estimates(members[1])
    e = estimates(out)
    gaps = [i for i, n in enumerate(HIGHWAY.targets) if n.startswith("dist_")]
    rest = [i for i in range(len(HIGHWAY.targets)) if i not in gaps]
    assert len(gaps) == 5 and HIGHWAY.targets[gaps[1]] == "dist_MM"
    np.testing.assert_allclose(e[:, gaps], np.minimum(a, b)[:, gaps], atol=1e-4)
    np.testing.assert_allclose(e[:, rest], ((a + b) / 2)[:, rest], atol=1e-4)
    assert not np.allclose(a[:, gaps], b[:, gaps], atol=0.5)   # the members differ: the test can tell min from mean


def test_the_drivers_predictor_reads_frames_through_it(members, tmp_path):
    """The closed loop's path (perception/predictor.py: channels-last weights, one frame at a time) gives the
    ensemble's own estimates."""
    out = tmp_path / "ens.pt"
    save_checkpoint(out, make([str(p) for p in members]))
    predictor = load_predictor(str(out))
    frame = FRAMES[0].permute(1, 2, 0).numpy()
    np.testing.assert_allclose(predictor([frame]), estimates(out)[0], atol=1e-3)


def test_gaps_averaged_when_asked(members, tmp_path):
    out = tmp_path / "mean.pt"
    save_checkpoint(out, make([str(p) for p in members], combine="mean"))
    np.testing.assert_allclose(estimates(out), (estimates(members[0]) + estimates(members[1])) / 2, atol=1e-4)


def test_members_that_read_otherwise_are_refused(members, tmp_path):
    temporal = member(tmp_path / "t.pt", 3, 0.5, 0.2, instants=(-1, 0))
    fast = member(tmp_path / "f.pt", 4, 0.5, 0.2, targets=HIGHWAY.targets + ("fast",))
    with pytest.raises(CheckpointError, match="another input"):
        make([str(members[0]), str(temporal)])
    assert make([str(members[0]), str(fast)])["spec"]["outputs"] == list(HIGHWAY.targets) + ["fast"]
    with pytest.raises(CheckpointError, match="at least two"):
        make([str(members[0])])


def test_the_command_refuses_in_one_line_and_writes_nothing(members, run_cli, tmp_path):
    out = tmp_path / "e.pt"
    for args in ([str(members[0])], [str(members[0]), str(tmp_path / "missing.pt")],
                 [str(members[0]), str(members[0])]):
        r = run_cli("ensemble", "--out", out, *args)    # `drivestudio ensemble`, in this process
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "error" in r.stderr, r.stderr
        assert not out.exists()
    r = run_cli("ensemble", "--out", out, *members)
    assert r.returncode == 0 and out.exists() and "Ensemble of 2" in r.stdout, r.stderr


def test_it_exports_to_onnx_with_the_documented_inputs(members, tmp_path):
    """A family without behavioural modes (the ensemble of MobileNets) exports too: the graph keeps its `modes`
    input (the tracer would drop an unused one) and agrees with PyTorch."""
    from perception.export import export_onnx  # here: onnxruntime is an optional extra, only for this test

    out = tmp_path / "ens.pt"
    save_checkpoint(out, make([str(p) for p in members]))
    info = export_onnx(out, tmp_path / "ens.onnx")
    assert (tmp_path / "ens.onnx").exists() and info["max_abs_difference"] < 1e-3
    import onnxruntime as ort  # here: as above

    session = ort.InferenceSession(str(tmp_path / "ens.onnx"), providers=["CPUExecutionProvider"])
    assert [i.name for i in session.get_inputs()] == ["images", "modes"]


def test_its_name_says_what_the_members_estimate_and_see_once(tmp_path):
    """Members with the 14th indicator: the ensemble's name carries "[+fast]" once (a member's title is its
    family's name alone; the labels are the ensemble's own)."""
    targets = (*HIGHWAY.targets, "fast")
    paths = [member(tmp_path / f"{k}.pt", k, 0.5, 0.2, targets=targets) for k in (1, 2)]
    name = describe(make([str(p) for p in paths])["spec"])
    assert name.count("[+fast]") == 1 and name.startswith("Ensemble of 2 MobileNet"), name


# a rear specialist: the extended set's outputs beyond the paper's 13, in an order of its own
REAR_SPECIALIST = ("closing_RB", "dist_LB", "fast", "lanes_left", "dist_RB", "closing_LB")


@pytest.fixture(scope="module")
def partial(tmp_path_factory, members):
    d = tmp_path_factory.mktemp("partial")
    rear = member(d / "rear.pt", 5, 0.4, 0.3, targets=REAR_SPECIALIST)
    fast = member(d / "fast.pt", 6, 0.5, 0.2, targets=HIGHWAY.targets + ("fast",))
    return rear, fast


def test_members_of_other_outputs_each_count_where_they_estimate(members, partial, tmp_path):
    """Two networks of the paper's 13, one of the 13 and `fast`, one of the rear outputs (and `fast`, `lanes_left`)
    in an order of its own: the ensemble estimates the union in the world's order; each paper output is combined
    over the three that estimate it, `fast` over two, the rear outputs are the specialist's own."""
    rear, fast = partial
    out = tmp_path / "ens.pt"
    save_checkpoint(out, make([str(members[0]), str(members[1]), str(fast), str(rear)]))
    names = load_model(out)[0].spec["outputs"]
    assert names == list(HIGHWAY.label_set("extended"))   # the union, in the declared order
    a, b, f, r = (estimates(p) for p in (*members, fast, rear))
    e = dict(zip(names, estimates(out).T))
    of = {"a": dict(zip(HIGHWAY.targets, a.T)), "b": dict(zip(HIGHWAY.targets, b.T)),
          "f": dict(zip(HIGHWAY.targets + ("fast",), f.T)), "r": dict(zip(REAR_SPECIALIST, r.T))}
    for n in HIGHWAY.targets:
        three = np.stack([of[k][n] for k in "abf"])
        want = three.min(axis=0) if n.startswith("dist_") else three.mean(axis=0)
        np.testing.assert_allclose(e[n], want, atol=1e-4, err_msg=n)
    np.testing.assert_allclose(e["fast"], (of["f"]["fast"] + of["r"]["fast"]) / 2, atol=1e-4)
    for n in ("lanes_left", "dist_LB", "dist_RB", "closing_LB", "closing_RB"):
        np.testing.assert_allclose(e[n], of["r"][n], atol=1e-4, err_msg=n)
    assert not np.allclose(of["r"]["dist_LB"], of["r"]["dist_RB"], atol=0.5)   # a swapped index would show


def test_a_partial_ensemble_drives_and_exports(members, partial, tmp_path):
    """The closed loop's predictor and the ONNX export give the same estimates as PyTorch."""
    from perception.export import export_onnx  # here: onnxruntime is an optional extra, only for this test

    out = tmp_path / "ens.pt"
    save_checkpoint(out, make([str(members[0]), str(members[1]), str(partial[0])]))
    frame = FRAMES[0].permute(1, 2, 0).numpy()
    np.testing.assert_allclose(load_predictor(str(out))([frame]), estimates(out)[0], atol=1e-3)
    assert export_onnx(out, tmp_path / "ens.onnx")["max_abs_difference"] < 1e-3
