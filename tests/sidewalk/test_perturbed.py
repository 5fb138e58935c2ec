"""The perturbed expert of the sidewalk's data (controller/sidewalk/perturbed.py, docs/sidewalk.md "Perturbed
episodes"): now and then a triangular impulse is added to the steering the car receives; every step's label (the
record's steer and motor) is the expert's own command for the state the car is in, the impulse only in the command
applied (the dataset's action column)."""

import numpy as np
import pytest

from controller.sidewalk import SidewalkExpert
from controller.sidewalk.perturbed import PerturbedExpert, PerturbParams, triangle
from core.worlds.sidewalk import SIDEWALK, STEP
from drivestudio.worlds.sidewalk.plugin import Plugin
from perception.moments import Moments
from perception.shards import Dataset
from tests.sidewalk.helpers import record


def test_the_impulse_is_a_triangle():
    assert triangle(0.0, 0.6) == 0.0 and triangle(0.6, 0.6) == 0.0
    assert triangle(0.3, 0.6) == pytest.approx(1.0)
    assert triangle(0.15, 0.6) == pytest.approx(0.5) and triangle(0.45, 0.6) == pytest.approx(0.5)
    assert triangle(-0.01, 0.6) == 0.0 and triangle(0.61, 0.6) == 0.0


def run(seed: int, steps: int = 3000):
    """(expert steer, applied steer, perturbed) per step on one record: the expert's command is the same every
    step, so the impulse is the difference."""
    rec = record(d=0.1, speed=2.0)
    driver = PerturbedExpert(seed)
    out = [driver.act(rec) for _ in range(steps)]
    expert = {e for _, e in out}
    assert len(expert) == 1 and next(iter(expert)) == tuple(SidewalkExpert().action(rec))   # the label: the expert
    applied = np.array([a[0] for a, _ in out])
    return out[0][1][0], applied, applied != out[0][1][0]


def stretches(flags: np.ndarray) -> list[tuple[int, int]]:
    """(first, last + 1) of every run of True."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], flags.astype(int), [0]))))
    return list(zip(edges[::2], edges[1::2]))


def test_impulses_and_pauses_keep_to_their_ranges():
    p = PerturbParams()
    _, _, perturbed = run(1)
    runs = stretches(perturbed)
    assert len(runs) >= 20
    for a, b in runs[:-1]:
        assert p.length[0] - 2 * STEP <= (b - a) * STEP <= p.length[1] + 2 * STEP
    for (_, b), (a, _) in zip(runs, runs[1:]):
        assert p.every[0] - 2 * STEP <= (a - b) * STEP <= p.every[1] + 2 * STEP
    assert runs[0][0] * STEP >= p.every[0] - 2 * STEP          # the first waits too: no impulse at the start


def test_an_impulse_moves_the_steering_by_its_peak_at_most_and_one_way():
    p = PerturbParams()
    expert, steer, perturbed = run(2)
    moved = np.abs(steer[perturbed] - expert)
    assert moved.max() <= p.peak[1] + 1e-9 and moved.max() >= p.peak[0]
    signs = {np.sign(steer[a:b] - expert).max() - np.sign(steer[a:b] - expert).min() for a, b in stretches(perturbed)}
    assert signs <= {0.0, 1.0}                                     # one impulse pushes one way
    ups = [np.sign((steer[a:b] - expert).sum()) for a, b in stretches(perturbed)]
    assert 1.0 in ups and -1.0 in ups                             # both ways over a run


def test_the_same_seed_perturbs_the_same_way():
    assert np.array_equal(run(3, 600)[1], run(3, 600)[1])
    assert not np.array_equal(run(3, 600)[1], run(4, 600)[1])


GENERATE = ["generate", "--world", "sidewalk", "--frames", "400",
            "--episode-frames", "200", "--set", "stereo.width=168", "--set", "stereo.height=94",
            "--paths", "park", "--modes",
            "direct,furtive", "--workers", "1", "--seed", "5"]


@pytest.fixture(scope="module")
def perturbed_data(tmp_path_factory):
    out = tmp_path_factory.mktemp("perturbed") / "data"
    from tests.helpers import make
    make(*GENERATE, "--perturbed", "1", "--out", out)
    return out


def test_every_label_is_the_experts_command_for_the_state_and_only_the_applied_one_is_perturbed(perturbed_data):
    """Row i holds the state the command of row i (action) was chosen on; the next row's steer and motor are the
    command of that step as the dataset records it (the label of a moment's first target)."""
    ds = Dataset(perturbed_data)
    assert [s.params["operation"] for s in ds.shards] == ["perturbed", "perturbed"]
    expert, names = SidewalkExpert(), SIDEWALK.truth_names
    kicked = 0
    for shard in ds.shards:
        table = ds.reader(shard).labels([*names, "action"])
        rows = np.stack([table.column(n).to_numpy().astype(np.float64) for n in names], axis=1)
        action = np.stack(table.column("action").to_numpy(zero_copy_only=False))
        assert (rows[:, SIDEWALK.index("operation")] == 0).all()          # all of it the expert's, all labelled
        labels = rows[1:, [SIDEWALK.index("steer"), SIDEWALK.index("motor")]]
        wanted = np.array([expert.action(r) for r in rows[:-1]])
        np.testing.assert_allclose(labels, wanted, atol=1e-5)            # float32 in the shard
        moved = np.abs(action[:-1, 0] - wanted[:, 0])
        assert moved.max() <= PerturbParams().peak[1] + 1e-5
        np.testing.assert_allclose(action[:-1, 1], wanted[:, 1], atol=1e-5)   # the motor is never perturbed
        kicked += int((moved > 1e-4).sum())
    assert kicked >= 20                                                   # the impulses are there
    assert len(Moments([perturbed_data], (94, 168))) == 2 * (200 - 11)   # every moment of every step


def test_a_plan_without_perturbed_episodes_is_the_plan_it_always_was():
    plugin = Plugin()
    base = {"modes": ["direct", "follow", "furtive"], "paths": [], "procedural": 3, "obstacles": 4.0,
            "correctional": 0.3, "width": 168, "height": 94, "fov": 56.0}
    before = plugin.plan(base, 3000, 250, 7)
    assert plugin.plan(base | {"perturbed": 0.0}, 3000, 250, 7) == before
    mixed = plugin.plan(base | {"perturbed": 0.5}, 3000, 250, 7)
    assert [e.seed for e in mixed] == [e.seed for e in before]
    assert all(m.params["operation"] == "correctional" for m, b in zip(mixed, before)
               if b.params["operation"] == "correctional")       # correctional episodes stay so
    assert {m.params["operation"] for m in mixed} == {"correctional", "perturbed", "expert"}
