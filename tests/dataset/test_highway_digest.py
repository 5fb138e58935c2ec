"""The highway's output is pinned: the same command and seed give the same labels and the same pixels as before
worlds were declared (digests taken with the version-1 code on a 60-frame set). A change that alters a pixel or a
label of the highway fails here."""
import hashlib

import numpy as np

from core.worlds.highway import INDICATORS
from perception.shards import Dataset
from tests.helpers import make

IMAGES = "d5262fd20cc70ecee9d35ccb6eba99cd5d6693e1c9608774220799b62f949a5a"
LABELS = "ae58514b58a12c42ffd2828ab3d9671a905ab6b6bd58880b4155b1378152fce7"
COMMAND = ["--frames", "60", "--episode-frames", "20", "--tracks", "oval,procedural:5", "--lanes", "1,2,3",
           "--cars", "12", "--workers", "2"]


def digests(root) -> tuple[str, str]:
    """SHA-256 of every frame's pixels, and of its labels, the expert's action and the other cars, in order."""
    ds = Dataset(root)
    images, labels = hashlib.sha256(), hashlib.sha256()
    for shard in ds.shards:
        reader = ds.reader(shard)
        for i in range(len(reader)):
            frames, rec = reader.row(i)
            images.update(np.ascontiguousarray(frames[0]).tobytes())
            values = [rec[n] for n in INDICATORS] + [rec["lanes_left"], rec["lanes"], rec["speed"],
                                                    rec["lane_width"], float(rec["in_lane"]), float(rec["on_marking"])]
            labels.update(np.asarray(values, np.float32).tobytes())
            labels.update(np.asarray([rec[k] for k in ("x", "y", "yaw", "s", "d")], np.float64).tobytes())
            labels.update(np.asarray(rec["action"], np.float32).tobytes())
            labels.update(np.asarray(rec["cars"], np.float32).reshape(-1).tobytes())
            labels.update(rec["perturbation"].encode())
    return images.hexdigest(), labels.hexdigest()


def test_the_highway_gives_the_same_pixels_and_labels(tmp_path):
    out = tmp_path / "ds"
    make("generate", "--out", out, *COMMAND)
    images, labels = digests(out)
    assert labels == LABELS, "a highway label, action or car pose changed"
    assert images == IMAGES, "a highway pixel changed"
