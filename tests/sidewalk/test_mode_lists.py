"""A list of behavioural modes that names none (an empty string, ",") is refused wherever modes are given, with one
line and status 2 before any work, as every other empty list is; it is never read as "all the modes"."""
from __future__ import annotations

import pytest

from core.declaration import DeclarationError
from core.worlds.highway import HIGHWAY
from core.worlds.sidewalk import SIDEWALK
from drivestudio.cli import main

EMPTY = ["", ",", " , "]


def _refused(capsys, argv: list[str], words: str) -> None:
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and words in err, (rc, err)


@pytest.fixture(scope="module")
def sidewalk_data(tmp_path_factory):
    out = tmp_path_factory.mktemp("modes") / "data"
    assert main(["generate", "--world", "sidewalk", "--frames", "60", "--episode-frames", "30",
                 "--set", "stereo.width=168", "--set", "stereo.height=94", "--paths", "park", "--workers", "1",
                 "--seed", "5", "--out", str(out)]) == 0
    return out


def test_the_declaration_reads_none_as_all_and_refuses_a_list_naming_no_mode():
    assert SIDEWALK.mode_list(None) == SIDEWALK.modes
    assert SIDEWALK.mode_list(" follow, direct ") == ("follow", "direct")
    for text in EMPTY:
        with pytest.raises(DeclarationError, match="names no mode"):
            SIDEWALK.mode_list(text)
    with pytest.raises(DeclarationError, match="unknown behavioural mode 'sneaky'"):
        SIDEWALK.mode_list("direct,sneaky")
    with pytest.raises(DeclarationError, match="unknown behavioural mode"):
        HIGHWAY.mode_list("direct")


@pytest.mark.parametrize("text", EMPTY)
def test_generate_refuses_modes_naming_no_mode(tmp_path, capsys, text):
    out = tmp_path / "data"
    _refused(capsys, ["generate", "--world", "sidewalk", "--modes", text, "--frames", "30", "--episode-frames",
                      "30", "--set", "stereo.width=168", "--set", "stereo.height=94", "--paths", "park",
                      "--workers", "1",
                      "--out", str(out)], f"--modes {text!r} names no mode")
    assert not out.exists()


@pytest.mark.parametrize("name", ["modes", "mtl"])
@pytest.mark.parametrize("text", EMPTY)
def test_train_refuses_modes_or_mtl_naming_no_mode(sidewalk_data, tmp_path, capsys, name, text):
    _refused(capsys, ["train", "--data", str(sidewalk_data), "--model", "z2color", "--epochs", "1",
                      "--batch-size", "6", "--out", str(tmp_path / "m.pt"), "--set", f"{name}={text}"],
             f"{name} {text.strip()!r} names no mode")   # --set reads the value without its outer spaces
    assert list(tmp_path.iterdir()) == []


def test_train_refuses_an_empty_mtl_for_a_family_without_modes(tmp_path, capsys, sidewalk_data):
    _refused(capsys, ["train", "--data", str(sidewalk_data), "--model", "alexnet", "--out", str(tmp_path / "m.pt"),
                      "--set", "mtl="], "mtl does not apply to --model alexnet")


@pytest.mark.parametrize("kw", [{"modes": ""}, {"modes": ","}, {"mtl": ""}, {"mtl": "direct,follow"}])
def test_the_trainer_called_as_a_library_refuses_them_too(sidewalk_data, tmp_path, kw):
    from perception.checkpoint import CheckpointError
    from perception.train import train
    from perception.training import config_from
    with pytest.raises(CheckpointError, match="names no mode|one mode"):
        train(config_from(data=str(sidewalk_data), model="z2color", out=str(tmp_path / "m.pt"), epochs=1,
                          batch_size=6, **kw), log=lambda *a, **k: None)
    assert list(tmp_path.iterdir()) == []
