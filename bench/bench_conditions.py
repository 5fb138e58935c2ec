"""Frames/s of rendering + ground truth in every named condition (docs/conditions.md), per renderer: what drawing a
condition costs against `clear` (issue 49's target for the fast renderer: within 20 %).

The scene of bench/bench_render.py (3-lane `oval`, 12 cars 8-74 m ahead, the host at 15 m/s), on a seed whose
road has street lamps (lit at night) and whose low sun is ahead on part of the lap.

    python bench/bench_conditions.py [--renderers numba,tiny] [--conditions seeded,clear,...] [--frames 600]
                                     [--rounds 3] [--insets none|mirror|sides] [--against DIR] [--json F]

Each renderer runs in a process of its own (bench/_conditions_worker.py) with a world per condition, the conditions
in turn, round by round, the order reversed every other round; a figure is the median of the rounds. Two figures a
condition: frames a second of wall time and of the process's CPU time (less inflated by other work on a shared
machine), and the render's milliseconds a frame; the ratios are to `clear`'s in the same run.

--against DIR measures another checkout of the repository in the same run (`git worktree add DIR COMMIT`): each
round is a process of this tree's and one of DIR's, in turn, so that both see the same machine; a table each.
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


def run(renderer: str, args, tree: Path = REPO, rounds: int | None = None, conditions: str | None = None) -> dict:
    """The worker's figures for `renderer`, the worker and the code of checkout `tree`."""
    env = {**os.environ, "PYTHONPATH": str(tree), "LP_NUM_THREADS": os.environ.get("LP_NUM_THREADS", "0")}
    r = subprocess.run([sys.executable, str(tree / "bench" / WORKER.name), "--renderer", renderer, "--conditions",
                        conditions or args.conditions, "--frames", str(args.frames), "--rounds",
                        str(rounds or args.rounds), "--insets", args.insets],
                       env=env, cwd=tree, capture_output=True, text=True, timeout=7200)
    if r.returncode != 0:
        tail = (r.stderr.strip().splitlines() or ["no output"])[-1]
        return {"renderer": renderer, "runs": {}, "skipped": f"the run failed: {tail}"}
    return json.loads(r.stdout.strip().splitlines()[-1])


def run_against(renderer: str, args) -> tuple[dict, dict]:
    """This tree's figures and those of the checkout args.against, a process of each a round, in turn (the
    conditions' order and the trees' reversed every other round)."""
    out: tuple[dict, dict] = ({"renderer": renderer, "runs": {}}, {"renderer": renderer, "runs": {}})
    names = args.conditions.split(",")
    for k in range(args.rounds):
        order = [(0, REPO), (1, args.against)] if k % 2 == 0 else [(1, args.against), (0, REPO)]
        for i, tree in order:
            res = run(renderer, args, tree, 1, ",".join(names if k % 2 == 0 else names[::-1]))
            if "skipped" in res:
                return res, res
            for name, rounds in res["runs"].items():
                out[i]["runs"].setdefault(name, []).extend(rounds)
    return out


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
    ap.add_argument("--against", type=Path, help="another checkout of the repository, measured in the same run")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    renderers = [r for r in args.renderers.split(",") if r]
    bad = [r for r in renderers if r not in RENDERERS] + \
        [c for c in args.conditions.split(",") if c not in CONDITIONS]
    if bad or not renderers:
        ap.error(f"unknown renderers or conditions: {', '.join(bad) or 'none given'}")
    if args.against is not None and not (args.against / "bench" / WORKER.name).is_file():
        ap.error(f"--against: {args.against} is not a checkout of this repository (no bench/{WORKER.name})")
    machine = {"cpu": cpu_model(), "cores": os.cpu_count(), "load": round(os.getloadavg()[0], 2),
               "date": datetime.date.today().isoformat()}
    tables = measure(renderers, args)
    print(f"oval, 3 lanes, 12 cars ahead, 280x210, insets {args.insets}, {args.frames} frames x {args.rounds} rounds "
          f"(medians); {machine['cpu']}, {machine['cores']} cores, load {machine['load']} at the start, "
          f"{machine['date']}")
    for tree, (out, skipped) in tables.items():
        print_table(tree, out, skipped)
    if args.json:
        this = tables[str(REPO)]
        args.json.write_text(json.dumps({"frames": args.frames, "rounds": args.rounds, "insets": args.insets,
                                         "machine": machine, "renderers": this[0], "skipped": this[1],
                                         "against": {t: {"renderers": o, "skipped": k} for t, (o, k) in tables.items()
                                                     if t != str(REPO)}}, indent=2) + "\n")


def measure(renderers: list[str], args) -> dict[str, tuple[dict, dict]]:
    """Per checkout (this one, then args.against's), per renderer: the figures, and why a renderer was not run."""
    tables: dict[str, tuple[dict, dict]] = {str(REPO): ({}, {})}
    if args.against is not None:
        tables[str(args.against)] = ({}, {})
    for r in renderers:
        results = run_against(r, args) if args.against is not None else (run(r, args),)
        for (out, skipped), res in zip(tables.values(), results):
            if "skipped" in res:
                skipped[r] = res["skipped"]
            else:
                out[r] = figures(res)
    return tables


def print_table(tree: str, out: dict, skipped: dict) -> None:
    print(f"{tree}:")
    print(f"{'renderer':8s} {'condition':9s} {'frames/s':>8s} {'per CPU s':>9s} {'render ms':>9s} "
          f"{'frame cost':>10s} {'render cost':>11s}  (cost: x clear's)")
    for r, rows in out.items():
        for x in rows:
            print(f"{r:8s} {x['condition']:9s} {x['frames_per_s']:8.0f} {x['frames_per_cpu_s']:9.0f} "
                  f"{x['render_ms']:9.3f} {x.get('cost_vs_clear', float('nan')):10.2f} "
                  f"{x.get('render_vs_clear', float('nan')):11.2f}")
    for r, why in skipped.items():
        print(f"{r}: not run ({why})")

if __name__ == "__main__":
    main()
