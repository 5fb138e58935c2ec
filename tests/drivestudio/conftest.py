"""Fixtures the drivestudio tests share."""
import pytest


@pytest.fixture(scope="module")
def highway_model(tmp_path_factory):
    """An untrained highway MobileNet's checkpoint: what a verb needs of a model before it drives or trains it."""
    from core.worlds.highway import HIGHWAY
    from perception.checkpoint import save_checkpoint
    from perception.models import build
    path = tmp_path_factory.mktemp("models") / "mobilenet.pt"
    model = build("mobilenet", HIGHWAY)
    save_checkpoint(path, {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    return path
