"""Frames/s of rendering + ground truth in every named condition (docs/conditions.md), per renderer: what drawing a
condition costs against `clear` (issue 49's target for the fast renderer: within 20 %).

The scene of bench/bench_render.py (3-lane `oval`, 12 cars 8-74 m ahead, the host at 15 m/s), on a seed whose
road has street lamps (lit at night) and whose low sun is ahead on part of the lap.

    python bench/bench_conditions.py [--renderers numba,tiny] [--conditions seeded,clear,...] [--frames 600]
                                     [--rounds 3] [--insets none|mirror|sides] [--json F]

Each renderer runs in a process of its own (bench/_conditions_worker.py) with a world per condition, the conditions
in turn, round by round, the order reversed every other round; a figure is the median of the rounds. Two figures a
condition: frames a second of wall time and of the process's CPU time (less inflated by other work on a shared
machine), and the render's milliseconds a frame; the ratios are to `clear`'s in the same run.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))   # run as a script: bench/ is a package of the repository

from bench.bench_render import cpu_model  # noqa: E402
from core.conditions import CONDITIONS  # noqa: E402
from sim.camera import RENDERERS  # noqa: E402

WORKER = Path(__file__).resolve().parent / "_conditions_worker.py"


def run(renderer: str, args) -> dict:
    env = {**os.environ, "PYTHONPATH": str(REPO), "LP_NUM_THREADS": os.environ.get("LP_NUM_THREADS", "0")}
    r = subprocess.run([sys.executable, str(WORKER), "--renderer", renderer, "--conditions", args.conditions,
                        "--frames", str(args.frames), "--rounds", str(args.rounds), "--insets", args.insets],
                       env=env, cwd=REPO, capture_output=True, text=True, timeout=7200)
    if r.returncode != 0:
        tail = (r.stderr.strip().splitlines() or ["no output"])[-1]
        return {"renderer": renderer, "runs": {}, "skipped": f"the run failed: {tail}"}
    return json.loads(r.stdout.strip().splitlines()[-1])


def figures(result: dict) -> list[dict]:
    """Per condition, the medians of its rounds and their ratios to clear's."""
    rows = []
    for name, rounds in result["runs"].items():
        rows.append({"condition": name, **{f: statistics.median(x[f] for x in rounds) for f in rounds[0]},
                     "rounds_frames_per_s": [round(x["frames_per_s"], 1) for x in rounds]})
    clear = next((r for r in rows if r["condition"] == "clear"), None)
    for r in rows:
        if clear is not None:
            r["cost_vs_clear"] = clear["frames_per_cpu_s"] / r["frames_per_cpu_s"]
            r["render_vs_clear"] = r["render_ms"] / clear["render_ms"]
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--renderers", default="numba,tiny", help="comma-separated, of " + ", ".join(RENDERERS))
    ap.add_argument("--conditions", default=",".join(CONDITIONS))
    ap.add_argument("--frames", type=int, default=600, help="frames of each condition in each round")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--insets", default="none", choices=("none", "mirror", "sides"))
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    renderers = [r for r in args.renderers.split(",") if r]
    bad = [r for r in renderers if r not in RENDERERS] + \
        [c for c in args.conditions.split(",") if c not in CONDITIONS]
    if bad or not renderers:
        ap.error(f"unknown renderers or conditions: {', '.join(bad) or 'none given'}")
    machine = {"cpu": cpu_model(), "cores": os.cpu_count(), "load": round(os.getloadavg()[0], 2),
               "date": datetime.date.today().isoformat()}
    out, skipped = {}, {}
    for r in renderers:
        res = run(r, args)
        if "skipped" in res:
            skipped[r] = res["skipped"]
        else:
            out[r] = figures(res)
    print(f"oval, 3 lanes, 12 cars ahead, 280x210, insets {args.insets}, {args.frames} frames x {args.rounds} rounds "
          f"(medians); {machine['cpu']}, {machine['cores']} cores, load {machine['load']} at the start, "
          f"{machine['date']}")
    print(f"{'renderer':8s} {'condition':9s} {'frames/s':>8s} {'per CPU s':>9s} {'render ms':>9s} "
          f"{'frame cost':>10s} {'render cost':>11s}  (cost: x clear's)")
    for r, rows in out.items():
        for x in rows:
            print(f"{r:8s} {x['condition']:9s} {x['frames_per_s']:8.0f} {x['frames_per_cpu_s']:9.0f} "
                  f"{x['render_ms']:9.3f} {x.get('cost_vs_clear', float('nan')):10.2f} "
                  f"{x.get('render_vs_clear', float('nan')):11.2f}")
    for r, why in skipped.items():
        print(f"{r}: not run ({why})")
    if args.json:
        args.json.write_text(json.dumps({"frames": args.frames, "rounds": args.rounds, "insets": args.insets,
                                         "machine": machine, "renderers": out, "skipped": skipped}, indent=2) + "\n")


if __name__ == "__main__":
    main()
