"""The driving score and the leaderboard (docs/benchmark.md defines every column).

Per route, as CARLA's Driving Score: route completion times the infraction penalty, where every infraction
multiplies the penalty by its coefficient (two collisions: 0.60 x 0.60 = 0.36):

    DS = RC x 0.60^collisions x 0.65^off-road events

Over a suite, the driving score and the route completion are the means over its routes (every route weighs the
same, as in CARLA's leaderboard); infractions and overtakes are per km over the whole suite; the speed is the
mean over routes of the model's mean speed divided by the oracle's on the same route.
"""
from __future__ import annotations

import csv
import io
import math

from drivestudio.worlds.highway.benchmark import scenarios
from drivestudio.worlds.highway.benchmark.route import completion
from drivestudio.worlds.highway.filters import FILTERS

PENALTY = {"collisions": 0.60, "off_road_events": 0.65}   # CARLA: collision with a vehicle 0.60, static 0.65

COLUMNS = (  # (key, heading, format) of the leaderboard
    ("driving_score", "driving score", "{:.1%}"),
    ("score_vs_oracle", "vs oracle", "{:.1%}"),
    ("route_completion", "completion", "{:.1%}"),
    ("collisions", "collisions", "{:d}"),
    ("collisions_per_km", "collisions/km", "{:.3f}"),
    ("off_road_events", "off-road", "{:d}"),
    ("off_road_per_km", "off-road/km", "{:.3f}"),
    ("overtakes_per_km", "overtakes/km", "{:.2f}"),
    ("speed_vs_oracle", "speed vs oracle", "{:.1%}"),
    ("lateral_rms_m", "lateral RMS [m]", "{:.3f}"),
    ("marking_share", "on markings outside lane changes", "{:.2%}"),
    ("distance_km", "km", "{:.1f}"),
)
ROUTE_COLUMNS = (
    ("driving_score", "DS", "{:.1%}"),
    ("route_completion", "completion", "{:.1%}"),
    ("collisions", "coll.", "{:d}"),
    ("off_road_events", "off-road", "{:d}"),
    ("overtakes", "overtakes", "{:d}"),
    ("lane_changes", "lane changes", "{:d}"),
    ("mean_speed_mps", "speed [m/s]", "{:.1f}"),
    ("speed_vs_oracle", "vs oracle", "{:.1%}"),
    ("lateral_rms_m", "lat. RMS [m]", "{:.3f}"),
    ("marking_time_s", "markings [s]", "{:.1f}"),
    ("distance_km", "km", "{:.2f}"),
    ("end", "end", "{}"),
)


def driving_score(route_completion: float, collisions: int, off_road_events: int) -> tuple[float, float]:
    """(driving score, infraction penalty) of one route."""
    penalty = PENALTY["collisions"] ** collisions * PENALTY["off_road_events"] ** off_road_events
    return route_completion * penalty, penalty


def route_row(result: dict, oracle: dict | None) -> dict:
    """One route of one model, scored."""
    m = result["metrics"]
    rc = completion(result)
    ds, penalty = driving_score(rc, m["collisions"], m["off_road_events"])
    km = m["distance_m"] / 1000.0
    ref = oracle["metrics"]["mean_speed_mps"] if oracle is not None else 0.0
    return {"route": result["route"], "condition": result.get("condition"), "driving_score": round(ds, 4),
            "penalty": round(penalty, 4),
            "route_completion": round(rc, 4), "end": result["end"], "driven_s": result["driven_s"],
            "distance_km": round(km, 3), "collisions": m["collisions"], "off_road_events": m["off_road_events"],
            "collisions_per_km": round(m["collisions"] / km, 4) if km else 0.0,
            "off_road_per_km": round(m["off_road_events"] / km, 4) if km else 0.0,
            "overtakes": m["overtakes"], "overtaken": m["overtaken"], "lane_changes": m["lane_changes"],
            "overtakes_per_km": round(m["overtakes"] / km, 3) if km else 0.0,
            "mean_speed_mps": m["mean_speed_mps"],
            "speed_vs_oracle": round(m["mean_speed_mps"] / ref, 4) if ref else 0.0,
            "lateral_rms_m": m["lateral_rms_m"], "lateral_steps": m["lateral_steps"],
            "marking_time_s": m["marking_time_s"], "marking_episodes": m["marking_episodes"],
            "in_lane_share": m["in_lane_share"], "loop_rate_hz": m["loop_rate_hz"], "wall_s": result["wall_s"],
            "clips": result["clips"], "clips_skipped": result["clips_skipped"],
            "controller_agreed": result["controller_agreed"], "scenario": result.get("scenario")}


def overall(rows: list[dict]) -> dict:
    """A model's figures over the whole suite."""
    n = len(rows)
    km = sum(r["distance_km"] for r in rows)
    driven = sum(r["driven_s"] for r in rows)
    steps = sum(r["lateral_steps"] for r in rows)
    col, off = sum(r["collisions"] for r in rows), sum(r["off_road_events"] for r in rows)
    return {"driving_score": round(sum(r["driving_score"] for r in rows) / n, 4),
            "route_completion": round(sum(r["route_completion"] for r in rows) / n, 4),
            "collisions": col, "off_road_events": off,
            "collisions_per_km": round(col / km, 4) if km else 0.0,
            "off_road_per_km": round(off / km, 4) if km else 0.0,
            "overtakes_per_km": round(sum(r["overtakes"] for r in rows) / km, 3) if km else 0.0,
            "lane_changes_per_km": round(sum(r["lane_changes"] for r in rows) / km, 3) if km else 0.0,
            "speed_vs_oracle": round(sum(r["speed_vs_oracle"] for r in rows) / n, 4),
            "lateral_rms_m": round(math.sqrt(sum(r["lateral_rms_m"] ** 2 * r["lateral_steps"] for r in rows)
                                             / steps), 4) if steps else 0.0,
            "marking_share": round(sum(r["marking_time_s"] for r in rows) / driven, 5) if driven else 0.0,
            "marking_time_s": round(sum(r["marking_time_s"] for r in rows), 1),
            "distance_km": round(km, 2), "driven_s": round(driven, 1),
            "clips": sum(len(r["clips"]) for r in rows), "collision_causes": collision_causes(rows)}


CAUSES = ("blind spot", "misread", "keeping")


def collision_causes(rows: list[dict]) -> dict[str, int]:
    """The collisions with a clip, by cause (clips.py): a lane change the controller would have started on the true
    gaps too ("blind spot"), one that only a misread gap allowed ("misread"), none ("keeping"), or not known (the
    change started before the clip's seconds)."""
    causes = [c.get("cause") or "unknown" for r in rows for c in r["clips"] if c["event"] == "collision"]
    return {k: causes.count(k) for k in CAUSES + ("unknown",)}


def leaderboard(suite, models, results: list[dict]) -> dict:
    """Every model's rows and overall figures, the oracle first: the leaderboard as JSON-able data."""
    by = {(r["model"], r["route"]): r for r in results}
    oracle = models[0]
    entries = []
    for m in models:
        rows = [route_row(by[(m.key, r.name)], by.get((oracle.key, r.name))) for r in suite.routes]
        entries.append({"model": m.label, "spec": m.text, "family": m.family, **{f: m.driver.get(f) for f in FILTERS},
                        "checkpoint": m.path, "overall": overall(rows), "routes": rows})
    top = entries[0]["overall"]["driving_score"]
    for e in entries:
        e["overall"]["score_vs_oracle"] = round(e["overall"]["driving_score"] / top, 4) if top else 0.0
    return {"suite": suite.as_dict(), "penalties": dict(PENALTY), "models": entries}


def _cell(fmt: str, value) -> str:
    if value is None:
        return "-"
    return fmt.format(value)


def markdown(board: dict, clip_root: str = "clips") -> str:
    """The leaderboard, the per-route tables and the clips, as Markdown."""
    suite = board["suite"]
    out = [f"# Benchmark: suite '{suite['name']}' ({len(suite['routes'])} routes, "
           f"{sum(r['seconds'] for r in suite['routes']) / 60:.3g} simulated minutes)", "",
           "Driving score = route completion x 0.60^collisions x 0.65^off-road events, per route, averaged over "
           "the routes (as CARLA's Driving Score); the oracle (exact indicators) is the upper bound.", "",
           "| model | " + " | ".join(h for _, h, _ in COLUMNS) + " |",
           "|---|" + "---|" * len(COLUMNS)]
    for e in board["models"]:
        o = e["overall"]
        out.append(f"| {e['model']} | " + " | ".join(_cell(f, o.get(k)) for k, _, f in COLUMNS) + " |")
    out.append("")
    if scenarios.has_scenarios(board):
        out += scenarios.markdown(board)
    out += ["## Per route", ""]
    for e in board["models"]:
        out += [f"### {e['model']}", "", "| route | " + " | ".join(h for _, h, _ in ROUTE_COLUMNS) + " |",
                "|---|" + "---|" * len(ROUTE_COLUMNS)]
        for r in e["routes"]:
            out.append(f"| {r['route']} | " + " | ".join(_cell(f, r.get(k)) for k, _, f in ROUTE_COLUMNS) + " |")
        out.append("")
    clips = [(e, r, c) for e in board["models"] for r in e["routes"] for c in r["clips"]]
    skipped = sum(r["clips_skipped"] for e in board["models"] for r in e["routes"])
    out += ["## Crash clips", ""]
    if not clips:
        out.append("No collision or off-road event: no clips." if not skipped else "")
    else:
        out += ["| model | route | event | t [s] | largest error in the 5 s before | contact | cause | clip |",
                "|---|---|---|---|---|---|---|---|"]
        for e, r, c in clips:
            blame = c["largest_error"]
            why = "none (exact indicators)" if blame is None else \
                f"{blame['indicator']} ({blame['normalised']:.2f} of scale)"
            out.append(f"| {e['model']} | {r['route']} | {c['event']} | {c['t']:.1f} | {why} | {c['contact']} | "
                       f"{c.get('cause') or '-'} | [{c['file'].rsplit('/', 1)[-1]}]({c['file']}) |")
        causes = [f"{e['model']}: " + ", ".join(f"{n} {k}" for k, n in e["overall"]["collision_causes"].items() if n)
                  for e in board["models"] if any(e["overall"].get("collision_causes", {}).values())]
        if causes:
            out += ["", "Collisions by cause (those with a clip; docs/benchmark.md): " + "; ".join(causes) + "."]
    if skipped:
        out += ["", f"{skipped} further events had no clip (at most --clips per route)."]
    return "\n".join(out).rstrip() + "\n"


def csv_text(board: dict) -> str:
    """One row per model: the leaderboard's columns, machine-readable."""
    buf = io.StringIO()
    keys = [k for k, _, _ in COLUMNS]
    w = csv.writer(buf, lineterminator="\n")
    extra = ["lane_changes_per_km", "marking_time_s", "driven_s", "clips"]
    w.writerow(["model", "spec"] + keys + extra)
    for e in board["models"]:
        w.writerow([e["model"], e["spec"]] + [e["overall"].get(k) for k in keys + extra])
    return buf.getvalue()


def routes_csv_text(board: dict) -> str:
    """One row per model and route."""
    buf = io.StringIO()
    keys = ["driving_score", "penalty", "route_completion", "end", "driven_s", "distance_km", "collisions",
            "off_road_events", "collisions_per_km", "off_road_per_km", "overtakes", "overtaken", "overtakes_per_km",
            "lane_changes", "mean_speed_mps", "speed_vs_oracle", "lateral_rms_m", "marking_time_s",
            "marking_episodes", "in_lane_share", "loop_rate_hz"]
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["model", "route"] + keys + ["clips"])
    for e in board["models"]:
        for r in e["routes"]:
            w.writerow([e["model"], r["route"]] + [r.get(k) for k in keys] + [len(r["clips"])])
    return buf.getvalue()
