"""Training samples/s of the real training loop (`drivestudio train` on real generated frames, data loading
included), per model family, before and after each speed-up: contiguous memory and PNG decoding every epoch (as
training ran before), then channels-last weights and inputs, then the frame cache (frames decoded once), then the
frame cache without a separate loader process.

Every configuration trains the same model from the same seed on the same frames; the runs alternate, round by
round, so that the machine's drift hits every configuration alike; the figure of a run is its samples/s over the
iterations after the first logged row (start-up excluded), and a configuration's figure is its best round.

`--before-tree DIR` runs the "before" configuration from another checkout of the project (say, a commit before a
speed-up that has no option to turn it off, such as the fused optimisers): `git worktree add DIR <commit>`, a
commit whose `train` takes the settings as `--set NAME=VALUE`.

    python bench/bench_training.py [--frames 600] [--rounds 2] [--families alexnet,mobilenet,mobilenet-h1]
                                   [--before-tree DIR] [--json F]
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

FAMILIES = {"alexnet": (["--model", "alexnet", "--batch-size", "15", "--set", "optimizer=adam", "--lr", "1e-4"], 24),
            "mobilenet": (["--model", "mobilenet"], 48),
            "mobilenet-h1": (["--model", "mobilenet", "--set", "history=1"], 48)}
VARIANTS = {"before (contiguous, PNG every epoch)": ["--set", "channels_last=false", "--set", "cache=false",
                                                    "--workers", "1"],
            "channels-last": ["--set", "cache=false", "--workers", "1"],
            "channels-last + frame cache": ["--workers", "1"],
            "channels-last + frame cache, no loader process": ["--workers", "0"]}


def drivestudio(*args: str, tree: Path | None = None) -> None:
    """A verb of this checkout, or of the checkout `tree` (python -m puts the working folder first on the path)."""
    subprocess.run([sys.executable, "-m", "drivestudio", *args], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, cwd=tree)


def samples_per_s(ckpt: Path) -> float:
    """Samples over seconds of the curve's rows after the first (equal-sized rows: the harmonic mean)."""
    rows = list(csv.DictReader(ckpt.with_name(ckpt.name + ".loss.csv").open()))[1:]
    rates = [float(r["samples_per_s"]) for r in rows]
    return len(rates) / sum(1 / r for r in rates) if rates else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=600, help="frames of the dataset trained on")
    ap.add_argument("--rounds", type=int, default=2, help="alternating rounds (the best is reported)")
    ap.add_argument("--families", default=",".join(FAMILIES))
    ap.add_argument("--before-tree", type=Path, help="run the first configuration from this checkout")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    if args.before_tree is not None and not (args.before_tree / "drivestudio" / "__main__.py").is_file():
        ap.error(f"--before-tree: {args.before_tree} is not a checkout of this project")
    before = next(iter(VARIANTS))
    work = Path(tempfile.mkdtemp(prefix="drivestudio-bench-train-"))
    try:
        data = work / "data"
        drivestudio("generate", "--out", str(data), "--frames", str(args.frames))
        best: dict = {}
        for _ in range(args.rounds):
            for fam in args.families.split(","):
                options, iterations = FAMILIES[fam]
                for variant, extra in VARIANTS.items():
                    ckpt = work / f"{fam}.pt"
                    for p in work.glob(f"{fam}.pt*"):
                        p.unlink()
                    shutil.rmtree(data / ".frames", ignore_errors=True)   # every cached run decodes once, as a user's
                    drivestudio("train", "--data", str(data), "--out", str(ckpt), *options, *extra, "--iterations",
                                str(iterations), "--set", f"val_every={10 * iterations}",
                                "--device", "cpu", tree=args.before_tree if variant == before else None)
                    rate = samples_per_s(ckpt)
                    best[(fam, variant)] = max(best.get((fam, variant), 0.0), rate)
        rows = []
        print(f"{'family':14s} {'configuration':48s} {'samples/s':>10s} {'x before':>9s}")
        for fam in args.families.split(","):
            base = best[(fam, next(iter(VARIANTS)))]
            for variant in VARIANTS:
                rate = best[(fam, variant)]
                print(f"{fam:14s} {variant:48s} {rate:10.1f} {rate / base:9.2f}")
                rows.append({"family": fam, "configuration": variant, "samples_per_s": rate, "vs_before": rate / base})
        if args.json:
            args.json.write_text(json.dumps({"rows": rows, "frames": args.frames, "cores": os.cpu_count()}, indent=1))
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
