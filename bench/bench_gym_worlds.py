"""Gymnasium steps/s of drivestudio/Highway-v0: one world before and after a change, and many worlds in one process.

One world: the default environment (oval, 3 lanes, 12 cars, a 280x210 frame every step, the Chen controller on the
true indicators), timed in a fresh process per run, alternating between this tree and --base (a commit, exported
into a temporary folder) round by round, so that both see the same machine; the median of the rounds. --renderers
adds, in the same rounds, this tree's environment drawing its frames with each other renderer (issue 48's before
and after: tiny, the default, against numba and gl). Then, this tree only: the affordance observation (no frame),
and 2 and 8 worlds in one process (the first on libsumo, the others each over TraCI to its own sumo), all steps of
all worlds together.

    python bench/bench_gym_worlds.py --base 8bda52c --rounds 5 --steps 300 [--renderers numba,gl] [--json F]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
WORKER = Path(__file__).resolve().parent / "_gym_worlds_worker.py"


def timed(tree: Path, steps: int, *extra: str) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    r = subprocess.run([sys.executable, str(WORKER), "--steps", str(steps), *extra], env=env, cwd=tree,
                       capture_output=True, text=True, timeout=1800)
    if r.returncode != 0:
        tail = (r.stderr.strip().splitlines() or ["no output"])[-1]
        raise SystemExit(f"bench_gym_worlds: the run in {tree} failed: {tail}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def export(rev: str, into: Path) -> Path:
    """The tree of commit `rev`, written into `into`."""
    archive = subprocess.run(["git", "-C", str(REPO), "archive", rev], capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", help="the commit to compare one world's steps/s with (default: no comparison)")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--steps", type=int, default=300, help="steps per run (of each world)")
    ap.add_argument("--renderers", default="", help="comma-separated: other renderers of this tree to time as well")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    others = [r for r in args.renderers.split(",") if r]
    out: dict = {"steps": args.steps, "rounds": args.rounds, "base": args.base}
    by_renderer: dict[str, list[dict]] = {r: [] for r in others}
    with tempfile.TemporaryDirectory(prefix="bench-gym-") as tmp:
        base = export(args.base, Path(tmp)) if args.base else None
        ours, theirs = [], []
        for k in range(args.rounds):
            if base is not None and k % 2:   # every other round the base goes first: neither always runs second
                theirs.append(timed(base, args.steps))
            ours.append(timed(REPO, args.steps))
            for r in (others if k % 2 else others[::-1]):
                by_renderer[r].append(timed(REPO, args.steps, "--renderer", r))
            if base is not None and not k % 2:
                theirs.append(timed(base, args.steps))
            print(f"round {k + 1}: this tree {ours[-1]['steps_per_s']:.0f} steps/s "
                  f"({ours[-1]['steps_per_cpu_s']:.0f} per CPU s)"
                  + (f", {args.base} {theirs[-1]['steps_per_s']:.0f} ({theirs[-1]['steps_per_cpu_s']:.0f})"
                     if theirs else "")
                  + "".join(f", {r} {v[-1]['steps_per_s']:.0f} ({v[-1]['steps_per_cpu_s']:.0f})"
                            for r, v in by_renderer.items()), flush=True)
    wall = [r["steps_per_s"] for r in ours]
    cpu = [r["steps_per_cpu_s"] for r in ours]
    out["one_world"] = {"this": statistics.median(wall), "rounds": wall, "this_cpu": statistics.median(cpu)}
    if theirs:
        base_wall = [r["steps_per_s"] for r in theirs]
        base_cpu = [r["steps_per_cpu_s"] for r in theirs]
        out["one_world"].update(base=statistics.median(base_wall), base_rounds=base_wall,
                                ratio=round(statistics.median(wall) / statistics.median(base_wall), 3),
                                base_cpu=statistics.median(base_cpu),
                                ratio_cpu=round(statistics.median(cpu) / statistics.median(base_cpu), 3))
    out["renderers"] = {r: {"steps_per_s": statistics.median(x["steps_per_s"] for x in v),
                            "steps_per_cpu_s": statistics.median(x["steps_per_cpu_s"] for x in v),
                            "rounds": [x["steps_per_s"] for x in v]} for r, v in by_renderer.items()}
    out["affordances"] = timed(REPO, args.steps, "--observation", "affordances")["steps_per_s"]
    out["many"] = []
    for k in (2, 8):
        r = timed(REPO, max(20, args.steps // k), "--worlds", str(k))
        out["many"].append({"worlds": k, "steps_per_s": r["steps_per_s"], "transports": r["transports"]})
    one = out["one_world"]
    print("| run | steps/s |\n|---|---|")
    print(f"| one world, camera, this tree | **{one['this']:.0f}** (median of {args.rounds}; "
          f"{one['this_cpu']:.0f} per CPU second) |")
    if theirs:
        print(f"| one world, camera, {args.base} | {one['base']:.0f} (ratio {one['ratio']:.2f}; "
              f"{one['base_cpu']:.0f} per CPU second, ratio {one['ratio_cpu']:.2f}) |")
    for r, v in out["renderers"].items():
        print(f"| one world, camera, renderer {r} | **{v['steps_per_s']:.0f}** ({v['steps_per_cpu_s']:.0f} per CPU "
              f"second; {v['steps_per_s'] / one['this']:.2f}x the default's) |")
    print(f"| one world, affordances (no frame) | {out['affordances']:.0f} |")
    for m in out["many"]:
        print(f"| {m['worlds']} worlds in one process, camera, all together | {m['steps_per_s']:.0f} "
              f"({', '.join(sorted(set(m['transports'])))}) |")
    if args.json:
        args.json.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
