"""Every dataset and checkpoint says which renderer drew its frames (issue 48): a generated dataset its own, a merged
one every source's, a network the union of what it learned from (its data, a fine-tuning's further data, an
ensemble's members)."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from core.worlds.highway import HIGHWAY
from perception.checkpoint import load_checkpoint, save_checkpoint
from perception.merge import Source, merge
from perception.models import add_renderers, make_spec
from perception.shards import MANIFEST, Dataset
from tests.perception import frames


def _redrawn(src: Path, out: Path, renderer: str | None) -> Path:
    """A copy of a dataset whose manifest names another renderer (or none, as datasets before the field)."""
    shutil.copytree(src, out, ignore=shutil.ignore_patterns(".frames"))
    manifest = json.loads((out / MANIFEST).read_text())
    manifest.pop("renderer")
    if renderer is not None:
        manifest["renderer"] = renderer
    (out / MANIFEST).write_text(json.dumps(manifest))
    return out


def test_a_generated_dataset_names_the_default_renderer():
    from sim.camera import DEFAULT_RENDERER

    assert Dataset(frames.dataset()).renderers == (DEFAULT_RENDERER,)


def test_a_dataset_that_does_not_say_has_no_renderer(tmp_path):
    assert Dataset(_redrawn(frames.dataset(), tmp_path / "old", None)).renderers == ()


def test_a_merged_dataset_names_every_sources_renderer(tmp_path):
    a = _redrawn(frames.dataset(), tmp_path / "a", "tiny")
    b = _redrawn(frames.dataset(), tmp_path / "b", "numba")
    merged = merge(tmp_path / "m", [Source(a), Source(b, train_only=True)], log=lambda *_: None)
    assert merged.renderers == ("numba", "tiny")
    assert Dataset(tmp_path / "m").manifest["renderers"] == ["numba", "tiny"]


def test_add_renderers_joins_and_stays_absent_while_none_is_known():
    spec = make_spec("gist", HIGHWAY)
    assert "renderers" not in add_renderers(spec, ())["input"]
    assert add_renderers(spec, {"tiny"})["input"]["renderers"] == ["tiny"]
    assert add_renderers(spec, ["numba", "tiny"])["input"]["renderers"] == ["numba", "tiny"]


def _untrained(path: Path, renderers) -> Path:
    """A MobileNet checkpoint as initialised, of frames drawn by `renderers`."""
    from perception.models import Regressor

    spec = add_renderers(make_spec("mobilenet", HIGHWAY), renderers)
    save_checkpoint(path, {"spec": spec, "state_dict": Regressor(spec).state_dict()})
    return path


def test_a_fitted_gist_records_its_datas_renderer():
    from sim.camera import DEFAULT_RENDERER

    assert load_checkpoint(frames.gist_checkpoint()[0])["spec"]["input"]["renderers"] == [DEFAULT_RENDERER]


@pytest.mark.parametrize("init", [None, "tiny", "gl"])
def test_a_trained_network_records_its_datas_renderer_and_its_inits(tmp_path, init):
    """A new network names its data's renderer; a fine-tuning adds it to those of the network it started from."""
    from perception.train import train
    from sim.camera import DEFAULT_RENDERER

    start = {"init": str(_untrained(tmp_path / "init.pt", {init}))} if init else {}
    out = tmp_path / "net.pt"
    train(frames.tiny_config("mobilenet", out, iterations=1, val_every=1, val_frames=4, **start), log=lambda *_: None)
    assert load_checkpoint(out)["spec"]["input"]["renderers"] == sorted({DEFAULT_RENDERER, init} - {None})


def test_an_ensemble_names_its_members_renderers(tmp_path):
    from drivestudio.ensemble import make

    paths = [str(_untrained(tmp_path / name, {renderer})) for name, renderer in (("a.pt", "tiny"), ("b.pt", "numba"))]
    assert make(paths)["spec"]["input"]["renderers"] == ["numba", "tiny"]
