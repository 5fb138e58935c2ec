"""Damaged weights are refused at load, and `export` writes only a verified graph (docs/errors.md, Checkpoints).

A checkpoint stores the SHA-256 of its tensors; a byte flipped inside a tensor no longer matches it. Weights that
are not finite (NaN, infinity) are refused whatever their digest. An export whose ONNX graph does not agree with
PyTorch (a NaN difference included) writes nothing, and a family ONNX cannot express is refused by name first.
"""
from __future__ import annotations

import zipfile

import numpy as np
import pytest
import torch

from core.worlds.highway import HIGHWAY
from core.worlds.sidewalk import SIDEWALK
from perception.checkpoint import DIGEST, CheckpointError, load_checkpoint, save_checkpoint, tensor_digest
from perception.models import Regressor, load_model, make_spec


def _save(path, model: Regressor, **extra) -> None:
    save_checkpoint(path, {"spec": model.spec, "state_dict": model.state_dict(), "train": {}, **extra})


def _gist(path, scale: float = 1.0):
    torch.manual_seed(0)
    model = Regressor(make_spec("gist", HIGHWAY))
    with torch.no_grad():
        model.net.weight.normal_().mul_(scale)
    _save(path, model)
    return model


def _flip_a_byte_inside(path, tensor: torch.Tensor) -> None:
    """Flip one byte of `tensor`'s stored bytes inside the torch archive at `path`, in place (the archive is
    uncompressed, so the tensor's bytes appear verbatim)."""
    data = bytearray(path.read_bytes())
    raw = tensor.contiguous().view(torch.uint8).numpy().tobytes()
    at = data.find(raw)
    assert at > 0 and data.find(raw, at + 1) < 0
    data[at + len(raw) // 2] ^= 0x40
    path.write_bytes(bytes(data))


def test_the_digest_of_the_tensors_is_stored_and_checked(tmp_path):
    model = _gist(tmp_path / "g.pt")
    ckpt = load_checkpoint(tmp_path / "g.pt")
    assert ckpt[DIGEST] == tensor_digest(model.state_dict())
    other = dict(model.state_dict())
    other["net.bias"] = other["net.bias"].clone()
    other["net.bias"][0] += 1e-6                      # one value changed: another digest
    assert tensor_digest(other) != ckpt[DIGEST]
    renamed = {("net.b" if k == "net.bias" else k): v for k, v in model.state_dict().items()}
    assert tensor_digest(renamed) != ckpt[DIGEST]     # names are part of it


def test_a_byte_flipped_inside_a_tensor_is_refused(tmp_path):
    model = _gist(tmp_path / "g.pt")
    _flip_a_byte_inside(tmp_path / "g.pt", model.state_dict()["net.weight"])
    assert zipfile.is_zipfile(tmp_path / "g.pt")      # still a well-formed archive: only the digest tells
    with pytest.raises(CheckpointError, match="is damaged: its weights are not the ones that were saved"):
        load_checkpoint(tmp_path / "g.pt")


def test_a_checkpoint_written_before_digests_still_loads(tmp_path):
    model = _gist(tmp_path / "g.pt")
    ckpt = torch.load(tmp_path / "g.pt", weights_only=True)
    del ckpt[DIGEST]
    torch.save(ckpt, tmp_path / "old.pt")
    net, _ = load_model(tmp_path / "old.pt")
    torch.testing.assert_close(net.net.weight, model.net.weight)


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), float("-inf")])
def test_weights_that_are_not_finite_are_refused(tmp_path, bad):
    model = _gist(tmp_path / "g.pt")
    with torch.no_grad():
        model.net.bias[3] = bad
    _save(tmp_path / "bad.pt", model)                 # its digest matches: the values themselves are refused
    with pytest.raises(CheckpointError, match="not finite .*'net.bias'"):
        load_checkpoint(tmp_path / "bad.pt")


def test_export_refuses_a_family_onnx_cannot_express_before_writing(tmp_path):
    pytest.importorskip("onnxruntime")
    from perception.export import export_onnx

    _gist(tmp_path / "g.pt")
    with pytest.raises(CheckpointError, match="holds a GIST model, which cannot be exported to ONNX: its anti-aliased"):
        export_onnx(tmp_path / "g.pt", tmp_path / "g.onnx")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.pt"]


def test_export_writes_nothing_when_the_graph_gives_nan(tmp_path):
    """Finite but huge weights of both signs overflow to inf - inf = NaN in both runtimes: the comparison of two
    NaNs is not a pass."""
    pytest.importorskip("onnxruntime")
    from perception.export import ExportError, export_onnx

    torch.manual_seed(1)
    model = Regressor(make_spec("z2color", SIDEWALK)).eval()
    with torch.no_grad():
        w = model.net.fc[-1].weight
        w.copy_(torch.where(torch.arange(w.shape[1]) % 2 == 0, 3e38, -3e38).expand_as(w))
    _save(tmp_path / "m.pt", model)
    (tmp_path / "m.onnx").write_bytes(b"an earlier export, kept")
    with pytest.raises(ExportError, match="differs from PyTorch by nan .* nothing written"):
        export_onnx(tmp_path / "m.pt", tmp_path / "m.onnx")
    assert (tmp_path / "m.onnx").read_bytes() == b"an earlier export, kept"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.onnx", "m.pt"]   # no temporary left


def test_an_exported_graph_is_written_once_verified(tmp_path):
    pytest.importorskip("onnxruntime")
    from perception.export import export_onnx

    torch.manual_seed(1)
    _save(tmp_path / "m.pt", Regressor(make_spec("z2color", SIDEWALK)).eval())
    r = export_onnx(tmp_path / "m.pt", tmp_path / "m.onnx")
    assert np.isfinite(r["max_abs_difference"]) and r["max_abs_difference"] < 1e-4
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.onnx", "m.pt"]
