"""Scripted scenarios as a benchmark suite (docs/scenarios.md, docs/benchmark.md): `benchmark --scenarios
FILE_OR_FOLDER` drives each scenario file as a route, and reports beside the driving score whether each model passed
each scenario (scenarios.csv and a table in leaderboard.md).

A folder's scenarios are its `*.json` files in name order (assets/scenarios/ is the shipped suite); every file is read
and checked whole before anything is driven, and two scenarios of one name are refused.
"""
from __future__ import annotations

import csv
import hashlib
import io
from pathlib import Path

from assets import ASSETS_DIR
from core.inputs import read_bytes, show_path
from drivestudio.errors import UsageError
from drivestudio.worlds.highway.benchmark.suite import MAX_ROUTES, NAME, Route, Suite, SuiteError

SCENARIOS_DIR = ASSETS_DIR / "scenarios"
SCENARIOS_CSV = "scenarios.csv"


def scenario_files(path) -> list[Path]:
    """The scenario files of a file or folder (a folder's *.json in name order)."""
    p = Path(path)
    if p.is_dir():
        files = sorted(f for f in p.glob("*.json") if f.is_file())
        if not files:
            raise UsageError(f"--scenarios {show_path(p)}: the folder holds no *.json scenario file")
        if len(files) > MAX_ROUTES:
            raise UsageError(f"--scenarios {show_path(p)}: {len(files)} scenarios; a run drives at most {MAX_ROUTES}")
        return files
    return [p]


def load_scenarios(path) -> Suite:
    """Every scenario of a file or folder as a route of one suite, checked whole (one line, exit status 2)."""
    from sim.highway.scripted import load_scripted  # lazy: the track library, only for scenarios
    files = scenario_files(path)
    routes: list[Route] = []
    seen: dict[str, Path] = {}
    digest = hashlib.sha256()
    for f in files:
        sc = load_scripted(f)
        if sc.name in seen:
            raise SuiteError(f"{show_path(f)}: scenario '{sc.name}' is named as {show_path(seen[sc.name])} is; "
                             f"scenario names must be unique")
        seen[sc.name] = f
        digest.update(read_bytes(f, "scenario"))
        routes.append(Route(sc.name, Path(sc.track_ref).name if sc.track_ref.endswith(".json") else sc.track_ref,
                            sc.lanes, sc.traffic, sc.seed, sc.host.lane, sc.seconds, sc.track_ref,
                            round(float(sc.track.length), 1), sc.path))
    p = Path(path)
    name = p.name if p.is_dir() else p.stem
    return Suite(name if NAME.fullmatch(name) else "scenarios", f"scripted scenarios: {show_path(p)}", tuple(routes),
                 show_path(p), digest.hexdigest())


# --- the table ----------------------------------------------------------------------------------------------------
def has_scenarios(board: dict) -> bool:
    return any(r.get("scenario") for e in board["models"] for r in e["routes"])


def verdict_text(scenario: dict | None) -> str:
    if not scenario:
        return "-"
    return "pass" if scenario["passed"] else "FAIL: " + "; ".join(scenario["failed"])


def markdown(board: dict) -> list[str]:
    """The scenarios table: a row per scenario, a column per model, and how many each model passed."""
    models = board["models"]
    out = ["## Scenarios", "", "| scenario | " + " | ".join(e["model"] for e in models) + " |",
           "|---|" + "---|" * len(models)]
    for i, r in enumerate(models[0]["routes"]):
        out.append(f"| {r['route']} | " + " | ".join(verdict_text(e["routes"][i].get("scenario")) for e in models)
                   + " |")
    passed = [sum(bool(r.get("scenario") and r["scenario"]["passed"]) for r in e["routes"]) for e in models]
    out.append("| **passed** | " + " | ".join(f"**{n} of {len(models[0]['routes'])}**" for n in passed) + " |")
    return out + [""]


def csv_text(board: dict) -> str:
    """One row per model and scenario: the verdict, what failed, the measures behind it and the trace's digest."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["model", "scenario", "passed", "failed", "collision_t", "left_lane_t", "min_time_gap_s",
                "min_time_gap_t", "events_fired", "steps", "trace_sha256"])
    for e in board["models"]:
        for r in e["routes"]:
            s = r.get("scenario")
            if s:
                w.writerow([e["model"], r["route"], s["passed"], "; ".join(s["failed"]), s["collision_t"],
                            s["left_lane_t"], s["min_time_gap_s"], s["min_time_gap_t"], len(s["events"]), s["steps"],
                            s["trace_sha256"]])
    return buf.getvalue()
