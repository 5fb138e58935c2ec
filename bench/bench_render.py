"""Frames/s of rendering + ground truth, every renderer with and without the insets, in one run (issue 48).

The host car drives along a 3-lane track at 15 m/s while 12 scripted cars keep pace in the three lanes 8-74 m
ahead, so every frame has 12 cars in view and the scenery streams past as in a real run. With the mirror, 4 more
cars follow the host; with the side views (and the mirror), 2 more drive level with it, one on each side.

    python bench/bench_render.py [--track oval] [--frames 1000] [--rounds 3] [--renderers tiny,egl,numba,gl]
                                 [--insets none,mirror,sides] [--json F]

Each round runs every renderer in a process of its own (bench/_render_worker.py; PyBullet's EGL plugin and OpenGL
do not share one), in turn, the order reversed every other round, so that each sees the same machine; a figure is
the median of the rounds. Two figures a run: frames a second of wall time, and frames a second of the process's CPU
time (all its threads), which other work on a shared machine inflates less. OpenGL's software rasteriser (Mesa's
llvmpipe, under renderers egl and gl) draws on the calling thread alone (LP_NUM_THREADS=0 unless set), so every
figure is one core's. A renderer this machine cannot run is left out, with the reason.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
from pathlib import Path

from sim.camera import RENDERERS

REPO = Path(__file__).resolve().parents[1]
WORKER = Path(__file__).resolve().parent / "_render_worker.py"
INSETS = ("none", "mirror", "sides")


def cpu_model() -> str:
    """The processor's model name, as lscpu gives it."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def run(renderer: str, insets: list[str], frames: int, track: str) -> dict:
    env = {**os.environ, "PYTHONPATH": str(REPO), "LP_NUM_THREADS": os.environ.get("LP_NUM_THREADS", "0")}
    r = subprocess.run([sys.executable, str(WORKER), "--renderer", renderer, "--insets", ",".join(insets),
                        "--frames", str(frames), "--track", track], env=env, cwd=REPO, capture_output=True,
                       text=True, timeout=3600)
    if r.returncode != 0:
        tail = (r.stderr.strip().splitlines() or ["no output"])[-1]
        return {"renderer": renderer, "runs": {}, "skipped": f"the run failed: {tail}"}
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--track", default="oval")
    ap.add_argument("--frames", type=int, default=1000, help="frames of each renderer and insets in each round")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--renderers", default=",".join(RENDERERS), help="comma-separated, of " + ", ".join(RENDERERS))
    ap.add_argument("--insets", default=",".join(INSETS), help="comma-separated, of " + ", ".join(INSETS))
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    renderers = [r for r in args.renderers.split(",") if r]
    insets = [i for i in args.insets.split(",") if i]
    bad = [r for r in renderers if r not in RENDERERS] + [i for i in insets if i not in INSETS]
    if bad or not renderers or not insets:
        ap.error(f"unknown renderers or insets: {', '.join(bad) or 'none given'}")
    machine = {"cpu": cpu_model(), "cores": os.cpu_count(), "lp_num_threads": os.environ.get("LP_NUM_THREADS", "0"),
               "load": round(os.getloadavg()[0], 2), "date": datetime.date.today().isoformat()}
    rounds: dict[tuple[str, str], list[dict]] = {}
    skipped: dict[str, str] = {}
    for k in range(args.rounds):
        for r in (renderers if k % 2 == 0 else renderers[::-1]):
            if r in skipped:
                continue
            res = run(r, insets, args.frames, args.track)
            if "skipped" in res:
                skipped[r] = res["skipped"]
            for inset, fig in res["runs"].items():
                rounds.setdefault((r, inset), []).append(fig)
        print(f"round {k + 1} of {args.rounds}: " + ", ".join(f"{r}/{i} {v[-1]['frames_per_s']:.0f}"
                                                             for (r, i), v in rounds.items()), flush=True)
    runs = []
    for r in renderers:
        for i in insets:
            if (r, i) in rounds:
                rs = rounds[r, i]
                runs.append({"renderer": r, "insets": i, **{f: statistics.median(x[f] for x in rs) for f in rs[0]},
                             "rounds_frames_per_s": [round(x["frames_per_s"], 1) for x in rs]})
    print(f"{args.track}, 3 lanes, 280x210, {args.frames} frames x {args.rounds} rounds (medians); {machine['cpu']}, "
          f"{machine['cores']} cores, LP_NUM_THREADS={machine['lp_num_threads']}, load {machine['load']} at the start, "
          f"{machine['date']}")
    print(f"{'renderer':8s} {'insets':6s} {'frames/s':>8s} {'per CPU s':>9s} {'render ms':>9s} {'truth ms':>8s}")
    for x in runs:
        print(f"{x['renderer']:8s} {x['insets']:6s} {x['frames_per_s']:8.0f} {x['frames_per_cpu_s']:9.0f} "
              f"{x['render_ms']:9.2f} {x['truth_ms']:8.2f}")
    for r, why in skipped.items():
        print(f"{r}: not run ({why})")
    if args.json:
        args.json.write_text(json.dumps({"track": args.track, "frames": args.frames, "rounds": args.rounds,
                                         "machine": machine, "runs": runs, "skipped": skipped}, indent=2) + "\n")


if __name__ == "__main__":
    main()
