"""`drivestudio evaluate` writes the MAE per indicator in the layout of Liu and Wang's Table 3 (Markdown, CSV, PNG),
split by regime and by lane count, with latency and throughput."""
import csv
import json

import numpy as np
import pytest

from core.worlds.highway import PAPER_INDICATORS
from drivestudio.cli import main
from perception.datasets import FrameDataset
from perception.evaluate import evaluate
from perception.highway.table3 import TABLE3, Table3Layout
from perception.predictor import load_predictor
from tests.perception.frames import alexnet_checkpoint, dataset, gist15_checkpoint, gist_checkpoint, workdir


@pytest.fixture(scope="module")
def report():
    out = workdir() / "evaluation"
    rc = main(["evaluate", "--data", str(dataset()), "--model", str(alexnet_checkpoint()[0]),
               "--model", str(gist_checkpoint()[0]), "--out", str(out), "--latency-frames", "3"])
    assert rc == 0
    return out


def test_table3_markdown_has_our_rows_and_the_papers(report):
    md = (report / "mae.md").read_text()
    header = "| model | angle | to_LL | to_ML | to_MR | to_RR | dist_LL | dist_MM | dist_RR | to_L | to_M | to_R | " \
             "dist_L | dist_R |"
    assert header in md
    for row in ("| AlexNet |", "| GIST + ridge |", "| *paper: GIST* | 0.051 | 1.033",
                "| *paper: AlexNet* | 0.048", "| *paper: VGG-16 (conv frozen)* | 0.062"):
        assert row in md
    assert "## By regime" in md and "## By lane count" in md and "## Speed" in md


def test_table3_csv_is_the_mae_of_each_indicator(report):
    rows = list(csv.DictReader((report / "mae.csv").open()))
    assert [r["model"] for r in rows] == ["AlexNet", "GIST + ridge"] + list(TABLE3)
    ours = rows[1]
    assert list(ours)[4:] == list(PAPER_INDICATORS)
    # recompute GIST's MAE of dist_MM from its predictions on the test frames
    predict = load_predictor(gist_checkpoint()[0])
    test = FrameDataset(dataset(), "test", PAPER_INDICATORS, normalised=False)
    truth = np.stack([test[i][2].numpy() for i in range(len(test))])
    pred = predict.batch([test[i][0].permute(1, 2, 0).numpy() for i in range(len(test))])[:, :13]
    mae = np.abs(pred - truth).mean(0)
    assert float(ours["dist_MM"]) == pytest.approx(mae[6], rel=1e-3)
    assert float(ours["angle"]) == pytest.approx(mae[0], rel=1e-3)


def test_regime_and_lane_breakdowns_partition_the_frames(report):
    test_frames = len(FrameDataset(dataset(), "test"))
    for name in ("mae_by_regime.csv", "mae_by_lanes.csv"):
        rows = [r for r in csv.DictReader((report / name).open()) if r["model"] == "AlexNet"]
        assert sum(int(r["frames"]) for r in rows) == test_frames, name
    regimes = {r["regime"] for r in csv.DictReader((report / "mae_by_regime.csv").open())}
    assert {"in lane only", "on marking only", "overlap (both)"} <= regimes


def test_bar_chart_speed_and_json_are_written(report):
    assert (report / "mae.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    speed = list(csv.DictReader((report / "speed.csv").open()))
    assert all(float(r["latency_ms_median"]) > 0 and float(r["throughput_fps"]) > 0 for r in speed)
    summary = json.loads((report / "evaluation.json").read_text())
    assert summary["split"] == "test" and len(summary["models"]) == 2
    assert summary["paper_table3"]["AlexNet"]["dist_R"] == 8.927


def test_models_with_extra_outputs_get_extra_columns():
    ev = evaluate(dataset(), [gist15_checkpoint(), gist_checkpoint()[0]], latency_frames=2, layout=Table3Layout())
    assert "| fast | lanes_left |" in ev.markdown
    rows = list(csv.reader(ev.files["mae.csv"].splitlines()))
    assert rows[0][-2:] == ["fast", "lanes_left"] and rows[2][-2:] == ["", ""]
