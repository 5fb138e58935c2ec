"""Running the generalisation protocol (protocol.py): every cell's routes with every model as jobs of one pool, then
one table of driving score, success rate and collisions and off-road events per km, per model and cell
(protocol.md, protocol.csv), the oracles' rows first.

A route succeeds when it is driven to its end without a collision (CARLA NoCrash's success: the goal reached in time
without a collision; a route here has a length in simulated time, and leaving the road ends it early).
"""
from __future__ import annotations

import csv
import io
import time
from dataclasses import replace
from pathlib import Path

from drivestudio.outputs import write_json, write_text
from drivestudio.worlds.highway.benchmark.models import ModelSpec
from drivestudio.worlds.highway.benchmark.protocol import Cell, Protocol
from drivestudio.worlds.highway.benchmark.route import RunOptions
from drivestudio.worlds.highway.benchmark.run import drive_all, jobs_for
from drivestudio.worlds.highway.benchmark.score import leaderboard

PROTOCOL_FILES = ("protocol.md", "protocol.csv", "protocol.json")
COLUMNS = ("model", "cell", "conditions", "tracks", "traffic", "routes", "driving_score", "success_rate",
           "collisions_per_km", "off_road_per_km", "collisions", "off_road_events", "distance_km")


def cell_row(model: dict, cell: Cell) -> dict:
    """One model's figures in one cell, from the cell's leaderboard entry of that model."""
    rows, o = model["routes"], model["overall"]
    success = sum(r["end"] == "finished" and r["collisions"] == 0 for r in rows) / len(rows)
    return {"model": model["model"], "cell": cell.name, "conditions": cell.conditions, "tracks": cell.tracks,
            "traffic": cell.traffic, "routes": len(rows), "driving_score": o["driving_score"],
            "success_rate": round(success, 4), "collisions_per_km": o["collisions_per_km"],
            "off_road_per_km": o["off_road_per_km"], "collisions": o["collisions"],
            "off_road_events": o["off_road_events"], "distance_km": o["distance_km"]}


def run_protocol(protocol: Protocol, models: list[ModelSpec], opts: RunOptions, out: Path, workers: int,
                 show_progress: bool = True, backend: str = "local") -> dict:
    """Drive every cell with every model; returns {"protocol", "run", "cells": [{cell, board}], "rows"}."""
    jobs = [j for cell in protocol.cells for condition, suite in cell.by_condition()
            for j in jobs_for(suite, models, replace(opts, condition=condition), out.resolve())]
    t0 = time.perf_counter()
    results = drive_all(jobs, workers, f"{len(protocol.cells)} cells x {len(models)} models", show_progress, backend)
    cells, rows = [], []
    for cell in protocol.cells:
        names = {r.name for r in cell.suite.routes}
        board = leaderboard(cell.suite, models, [r for r in results if r["route"] in names])
        cells.append({"cell": cell.name, "condition": cell.condition, "board": board})
        rows += [cell_row(m, cell) for m in board["models"]]
    rows.sort(key=lambda r: [m.label for m in models].index(r["model"]))
    return {"protocol": {"name": protocol.name, "path": protocol.path, "sha256": protocol.sha256,
                         "conditions": protocol.conditions, "tracks": protocol.tracks, "traffic": protocol.traffic,
                         "seconds": protocol.seconds, "generator": protocol.generator},
            "run": {"workers": workers, "wall_time_s": round(time.perf_counter() - t0, 1),
                    "renderer": opts.renderer, "device": opts.device, "transport": opts.transport},
            "cells": cells, "rows": rows}


def markdown(report: dict) -> str:
    p = report["protocol"]
    lines = [f"# Generalisation protocol '{p['name']}'", "",
             f"Conditions: training {', '.join(p['conditions']['training'])}; new {', '.join(p['conditions']['new'])}."
             f" Tracks: training {', '.join(p['tracks']['training'])}; new {', '.join(p['tracks']['new'])}. Traffic "
             f"(AI cars per km of lane): {', '.join(f'{k} {v:g}' for k, v in p['traffic'].items())}. "
             f"{p['seconds']:g} s a route; renderer {report['run']['renderer']}.", "",
             "| model | cell | routes | driving score | success | collisions / km | off-road / km |",
             "|---|---|---|---|---|---|---|"]
    for r in report["rows"]:
        lines.append(f"| {r['model']} | {r['cell']} | {r['routes']} | {100 * r['driving_score']:.1f}% | "
                     f"{100 * r['success_rate']:.0f}% | {r['collisions_per_km']:.3f} | {r['off_road_per_km']:.3f} |")
    return "\n".join(lines) + "\n"


def csv_text(report: dict) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    w.writerows(report["rows"])
    return buf.getvalue()


def write_protocol(out: Path, report: dict) -> str:
    text = markdown(report)
    write_text(out / "protocol.md", text)
    write_text(out / "protocol.csv", csv_text(report))
    write_json(out / "protocol.json", report)
    return text
