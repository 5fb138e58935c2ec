"""The closed-loop benchmark (docs/benchmark.md): fixed routes, a driving score, and why each crash happened.

    suite.py    the suite file format and its checks (the default suite: assets/suites/default.json)
    models.py   the rows: oracle, or a highway checkpoint with optional smoothing
    route.py    one route with one model through drive's loop (in process or over the bridge), its metrics
    clips.py    crash clips: the 5 s before every collision or off-road event, and the indicator to blame
    score.py    the driving score and the leaderboard (Markdown, CSV, JSON)
    run.py      the routes driven in parallel, as jobs of the pool (local processes or Ray tasks)
"""
from drivestudio.worlds.highway.benchmark.models import ModelSpec, check_models
from drivestudio.worlds.highway.benchmark.route import RunOptions, run_route
from drivestudio.worlds.highway.benchmark.run import run_benchmark
from drivestudio.worlds.highway.benchmark.score import PENALTY, driving_score
from drivestudio.worlds.highway.benchmark.suite import DEFAULT_SUITE, Route, Suite, SuiteError, load_suite

__all__ = ["ModelSpec", "check_models", "RunOptions", "run_route", "run_benchmark", "PENALTY", "driving_score",
           "DEFAULT_SUITE", "Route", "Suite", "SuiteError", "load_suite"]
