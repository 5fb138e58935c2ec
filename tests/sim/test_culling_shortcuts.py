"""The shortcuts the truth and the render take agree with the long way: a rectangle clear of the host along one of
its axes is not an overlap (sim/collision.py), and the render's culling blocks (sim/render/raster.py) cover every
triangle of a body once, in order, each inside its sphere."""
from __future__ import annotations

import numpy as np

from sim import collision
from sim.render.raster import BLOCK, SPAN, _blocks


def test_the_clear_along_an_axis_shortcut_never_changes_an_overlap(monkeypatch):
    rng = np.random.default_rng(0)
    host = (0.0, 0.0, 0.3, 4.6, 1.9)
    others = np.column_stack([rng.uniform(-6, 6, 4000), rng.uniform(-4, 4, 4000), rng.uniform(-np.pi, np.pi, 4000),
                              rng.uniform(3.5, 5.0, 4000), rng.uniform(1.6, 2.1, 4000)])
    fast = collision.overlaps(host, others)
    monkeypatch.setattr(collision, "_apart_along_a", lambda a, b: np.zeros(len(b), dtype=bool))
    full = collision.overlaps(host, others)
    assert np.array_equal(fast, full) and 0 < full.sum() < len(full)


def test_culling_blocks_cover_each_body_in_order_inside_their_spheres():
    rng = np.random.default_rng(1)
    counts = np.array([1, 70, 5, 200])
    corners = np.concatenate([rng.uniform(0, 30, (1, 3, 3)) + rng.uniform(-1, 1, (n, 3, 3)) * (3 if n > 60 else 20)
                              for n in counts]).astype(np.float32)
    firsts = np.cumsum(counts) - counts
    blocks, spheres, first, end = _blocks(corners, firsts, counts)
    for b, (f, n) in enumerate(zip(firsts, counts)):
        mine = blocks[first[b]:end[b]]
        assert mine[0, 0] == f and mine[-1, 1] == f + n and np.array_equal(mine[1:, 0], mine[:-1, 1])
    for (s, e), (cx, cy, cz, r) in zip(blocks, spheres):
        p = corners[s:e].reshape(-1, 3)
        assert np.all(np.linalg.norm(p - (cx, cy, cz), axis=1) <= r + 1e-9)
        span = (p.max(axis=0) - p.min(axis=0)).max()
        assert e - s <= BLOCK and (span <= SPAN or e - s == 1)
    assert len(blocks) > len(counts)   # the large bodies were cut
