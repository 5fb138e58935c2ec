"""The sidewalk's closed-loop metrics as its plugin makes them (controller/sidewalk/metrics.py): fed with the world's
observations, the same report as the metrics fed with the truth records; the correction rule's take-overs by clause
reported under correctional operation only."""
import numpy as np

from controller.sidewalk import PoorDriver, SidewalkMetrics
from drivestudio import worlds
from drivestudio.worlds.sidewalk.drivers import Supervisor
from sim.sidewalk.world import SidewalkConfig, SidewalkWorld


def run(operation: str, seconds: float = 20.0):
    w = SidewalkWorld(SidewalkConfig(path="park", seed=2, obstacles=4.0, render=False))
    sup, driver = Supervisor(w, operation), PoorDriver(seed=4)
    metrics, plain = worlds.get("sidewalk").metrics(w), SidewalkMetrics(w.dt)
    obs = w.observe(False)
    for _ in range(int(seconds / w.dt)):
        applied, _ = sup(obs, np.array(driver.act(obs.record)))
        obs = w.step(applied, False)
        metrics.observe(obs)
        plain.update(obs.record)
    w.close()
    return metrics, plain, sup


def test_the_plugins_metrics_report_the_take_overs_of_correctional_operation():
    metrics, plain, sup = run("correctional")
    report = metrics.report()
    assert report["rule"] == "safety" and report["take_overs_by_clause"] == sup.rule.tally.report(metrics.dt)
    assert sum(v["take_overs"] for v in report["take_overs_by_clause"].values()) == report["corrections"] >= 1
    assert {k: v for k, v in report.items() if k not in ("rule", "take_overs_by_clause")} == \
        {k: v for k, v in plain.report().items() if k not in ("rule", "take_overs_by_clause")}
    assert "take-overs: " in metrics.table()


def test_no_rule_is_reported_without_correctional_operation():
    metrics, plain, _ = run("autonomous", seconds=3.0)
    report = metrics.report()
    assert report["rule"] is None and report["take_overs_by_clause"] is None
    assert report == plain.report()
