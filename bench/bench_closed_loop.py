"""Closed-loop rate: world and driver in two processes over shared memory (issue 4's target: 60 Hz, render-bound).

    python bench/bench_closed_loop.py [--model oracle] [--model runs/alexnet.pt ...] [--seconds 60] [--json F]

Runs `drivestudio drive` (3-lane oval, 12 AI cars, lock-step) per model and prints the loop rate and where the
time went, from the run's metrics.json.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", action="append", help="oracle (default) or a checkpoint; repeatable")
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds per run")
    ap.add_argument("--free-running", action="store_true")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    rows = []
    models = args.model or ["oracle"]
    print("| driver | loop Hz | render ms | transfer ms | perception ms | control ms | sim+traffic+truth ms |")
    print("|---|---|---|---|---|---|---|")
    for model in models:
        with tempfile.TemporaryDirectory() as tmp:
            cmd = [sys.executable, "-m", "drivestudio", "drive", "--model", model, "--track", "oval", "--lanes", "3",
                   "--cars", "12", "--seconds", str(args.seconds), "--out", tmp]
            subprocess.run(cmd + (["--free-running"] if args.free_running else []), check=True,
                           stdout=subprocess.DEVNULL)
            m = json.loads((Path(tmp) / "metrics.json").read_text())
        st = m["stage_ms_per_step"]
        sim_ms = st["physics"] + st["traffic"] + st["truth"]
        print(f"| {model} | {m['loop_rate_hz']:.0f} | {st['render']:.2f} | {st['transfer']:.2f} | "
              f"{st['perception']:.2f} | {st['control']:.3f} | {sim_ms:.2f} |", flush=True)
        rows.append({"model": model, "loop_hz": m["loop_rate_hz"], "stage_ms_per_step": st})
    if args.json:
        args.json.write_text(json.dumps({"seconds": args.seconds, "free_running": args.free_running, "runs": rows},
                                        indent=2) + "\n")


if __name__ == "__main__":
    main()
