"""A dataset drawn by renderer numba is the dataset renderer tiny draws (docs/rendering.md): the same episodes with the
same seed give the same labels and, frame for frame, the same pixels but for a rare edge pixel. This is why a network
trained on one renderer's frames drives on the other's (docs/benchmarks.md) and why numba is the default."""
from __future__ import annotations

import numpy as np

from drivestudio import worlds
from drivestudio.generate import GenerateConfig, generate
from perception.shards import Dataset, read_manifest
from sim.highway.config import WorldConfig


def frames_and_labels(renderer: str, out) -> tuple[list[np.ndarray], list[dict]]:
    plugin = worlds.get("highway")
    options = plugin.generate_options(WorldConfig(renderer=renderer), {"tracks": "hairpins", "lane_counts": "3",
                                                                       "car_range": "8-8"})
    cfg = GenerateConfig(frames=16, episode_frames=16, renderer=renderer, warmup=1.0, options=options)
    generate(out, cfg, workers=1, show_progress=False, log=lambda *a: None)
    assert read_manifest(out)["renderer"] == renderer
    ds = Dataset(out)
    rows = [ds.reader(shard).row(i) for shard in ds.shards for i in range(shard.frames)]
    return [images[0] for images, _ in rows], [record for _, record in rows]


def test_numba_draws_tinys_dataset(tmp_path):
    tiny, tiny_labels = frames_and_labels("tiny", tmp_path / "tiny")
    numba, numba_labels = frames_and_labels("numba", tmp_path / "numba")
    assert len(tiny) == len(numba) == 16 and tiny_labels == numba_labels
    differing = [int((a != b).any(axis=2).sum()) for a, b in zip(tiny, numba)]
    assert sum(d == 0 for d in differing) >= 13 and max(differing) <= 3, differing
