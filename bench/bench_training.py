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

`--precision` compares float32 (`amp=false`) with the bfloat16 autocast the trainer uses where the CPU computes
bfloat16 natively (`amp`, the default), both in the fastest configuration above (channels-last, the frame cache, no
loader process, as the recipe trains): iterations a minute side by side, the median of the rounds (a shared machine
drifts, so the rounds alternate and the median is the figure), each round's ratio. `--threads 1` measures a
network as the recipe trains it, one thread each beside the others; `--side-by-side N` trains N copies at once in
each precision (the recipe trains three at once on two cores: `--threads 1 --side-by-side 3`), the figure then each
copy's iterations a minute, their mean.

`--allocator` compares glibc's allocator as it comes with the one the trainings set up (core/allocator.py: freed memory
kept, no block served by mmap), both in bfloat16 where native, the same way. `--input` compares the input path in
tensor code (a sample's frames concatenated by numpy, the batch averaged and scaled by tensor operations) with the
compiled one (perception/input_kernels.py), the same way.

    python bench/bench_training.py [--frames 600] [--rounds 2] [--families alexnet,mobilenet,mobilenet-h1]
                                   [--before-tree DIR] [--json F]
    python bench/bench_training.py --precision|--allocator|--input [--rounds 5] [--threads N] [--side-by-side N]
                                   [--families alexnet,mobilenet-h1] [--iterations N] [--data DIR]
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# each family at its default batch; mobilenet-h1 is the recipe's network (the previous frame too)
FAMILIES = {"alexnet": (["--model", "alexnet", "--batch-size", "15", "--set", "optimizer=adam", "--lr", "1e-4"], 24),
            "mobilenet": (["--model", "mobilenet", "--batch-size", "32"], 48),
            "mobilenet-h1": (["--model", "mobilenet", "--batch-size", "32", "--set", "history=1"], 48)}
VARIANTS = {"before (contiguous, PNG every epoch)": ["--set", "channels_last=false", "--set", "cache=false",
                                                    "--workers", "1"],
            "channels-last": ["--set", "cache=false", "--workers", "1"],
            "channels-last + frame cache": ["--workers", "1"],
            "channels-last + frame cache, no loader process": ["--workers", "0"]}
PRECISIONS = {"float32": ["--workers", "0", "--set", "amp=false"], "bfloat16 autocast": ["--workers", "0"]}
# a verb with glibc's own allocator settings (core/allocator.py switched off before the command line is read)
GLIBC_DEFAULT = ("import sys, core.allocator as a; a.keep_freed_memory = lambda: False; "
                 "from drivestudio.cli import main; sys.exit(main())")
# a verb whose frames are stacked and scaled by the tensor code alone (perception/input_kernels.py not used)
TENSOR_INPUT = ("import sys, numpy as np, perception.input_kernels as k, perception.models as m; "
                "k.interleave = lambda images: np.concatenate(images, axis=2); "
                "m.Regressor._compiled_path = lambda self, images, block=1: False; "
                "from drivestudio.cli import main; sys.exit(main())")
# name: (train options, a `python -c` program in place of `python -m drivestudio`, or None)
PAIRS: dict[str, dict[str, tuple[list[str], str | None]]] = {
    "precision": {"float32": (PRECISIONS["float32"], None), "bfloat16": (PRECISIONS["bfloat16 autocast"], None)},
    "allocator": {"glibc default": (["--workers", "0"], GLIBC_DEFAULT), "kept": (["--workers", "0"], None)},
    "input": {"tensor code": (["--workers", "0"], TENSOR_INPUT), "compiled": (["--workers", "0"], None)}}


def drivestudio(*args: str, tree: Path | None = None, env: dict | None = None) -> None:
    """A verb of this checkout, or of the checkout `tree` (python -m puts the working folder first on the path)."""
    subprocess.run([sys.executable, "-m", "drivestudio", *args], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, cwd=tree, env=None if env is None else {**os.environ, **env})


def drivestudio_together(argvs: list[list[str]], env: dict, program: str | None = None) -> None:
    """Verbs of this checkout run at once (trainings side by side, as the recipe runs them), each by `python -c
    program` where one is given."""
    launch = [sys.executable, "-c", program] if program else [sys.executable, "-m", "drivestudio"]
    procs = [subprocess.Popen([*launch, *a], stdout=subprocess.DEVNULL, cwd=Path(__file__).resolve().parents[1],
                              stderr=subprocess.DEVNULL, env={**os.environ, **env}) for a in argvs]
    if any(p.wait() != 0 for p in procs):
        raise SystemExit("a training of the benchmark failed")


def samples_per_s(ckpt: Path) -> float:
    """Samples over seconds of the curve's rows after the first (equal-sized rows: the harmonic mean)."""
    rows = list(csv.DictReader(ckpt.with_name(ckpt.name + ".loss.csv").open()))[1:]
    rates = [float(r["samples_per_s"]) for r in rows]
    return len(rates) / sum(1 / r for r in rates) if rates else 0.0


def batch_of(options: list[str]) -> int:
    return int(options[options.index("--batch-size") + 1])


def cpu_name() -> str:
    """The processor's model name and its bfloat16 units, as the kernel lists them."""
    try:
        info = Path("/proc/cpuinfo").read_text()
    except OSError:
        return platform.processor() or platform.machine()
    name = next((line.split(":", 1)[1].strip() for line in info.splitlines() if line.startswith("model name")),
                platform.machine())
    flags = next((line.split(":", 1)[1].split() for line in info.splitlines() if line.startswith("flags")), [])
    units = [f for f in ("avx512_bf16", "amx_bf16") if f in flags]
    return f"{name} ({', '.join(units) or 'no native bfloat16'})"


def pair(args) -> None:
    """Two settings of one training (PAIRS: float32 against bfloat16 autocast, or glibc's allocator against freed
    memory kept), alternating round by round: iterations a minute, medians."""
    configs = PAIRS[args.compare]
    work = Path(tempfile.mkdtemp(prefix=f"drivestudio-bench-{args.compare}-"))
    families = args.families.split(",")
    env = {} if args.threads is None else {"OMP_NUM_THREADS": str(args.threads), "MKL_NUM_THREADS": str(args.threads)}
    threads = args.threads or os.cpu_count()
    try:
        data = args.data or work / "data"
        if args.data is None:
            drivestudio("generate", "--out", str(data), "--frames", str(args.frames))
        per_min: dict = {(fam, p): [] for fam in families for p in configs}
        loads = [os.getloadavg()[0]]
        for r in range(args.rounds):
            for fam in families:
                options, iterations = FAMILIES[fam]
                # the order flips every round: neither precision always runs first after the other family
                iterations = args.iterations or iterations
                for name in (list(configs) if r % 2 == 0 else list(reversed(configs))):
                    extra, program = configs[name]
                    ckpts = [work / f"{fam}-{k}.pt" for k in range(args.side_by_side)]
                    for p in work.glob(f"{fam}-*.pt*"):
                        p.unlink()
                    drivestudio_together([["train", "--data", str(data), "--out", str(ckpt), *options,
                                           *extra, "--iterations", str(iterations), "--set",
                                           f"val_every={10 * iterations}", "--device", "cpu"] for ckpt in ckpts], env,
                                         program)
                    per_min[(fam, name)].append(statistics.mean(samples_per_s(c) for c in ckpts) * 60
                                                / batch_of(options))
            loads.append(os.getloadavg()[0])
            print(f"round {r + 1}/{args.rounds} done, load average {loads[-1]:.1f}", file=sys.stderr, flush=True)
        fp32, bf16 = configs
        print(f"{cpu_name()}, {threads} thread(s), {args.side_by_side} training(s) at once, {args.rounds} "
              f"alternating rounds, load average "
              f"{min(loads):.1f}-{max(loads):.1f}, {time.strftime('%Y-%m-%d')}")
        print(f"{'family':14s} {'batch':>5s} {fp32 + ' it/min':>20s} {bf16 + ' it/min':>20s} {'x ' + fp32:>16s}  "
              f"rounds ({bf16} / {fp32})")
        rows = []
        for fam in families:
            a, b = per_min[(fam, fp32)], per_min[(fam, bf16)]
            ratios = [y / x for x, y in zip(a, b)]
            ma, mb = statistics.median(a), statistics.median(b)
            print(f"{fam:14s} {batch_of(FAMILIES[fam][0]):5d} {ma:20.1f} {mb:20.1f} {mb / ma:16.2f}  "
                  + " ".join(f"{x:.2f}" for x in ratios))
            for name, rates in ((fp32, a), (bf16, b)):
                rows.append({"family": fam, "configuration": name, "iterations_per_min": statistics.median(rates),
                             "samples_per_s": statistics.median(rates) * batch_of(FAMILIES[fam][0]) / 60,
                             "vs_before": statistics.median(rates) / ma, "rounds": rates,
                             "round_ratios": ratios if name == bf16 else None})
        if args.json:
            args.json.write_text(json.dumps({"rows": rows, "frames": args.frames, "cores": os.cpu_count(),
                                             "threads": threads, "side_by_side": args.side_by_side, "cpu": cpu_name(),
                                             "load_average": loads},
                                            indent=1))
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=600, help="frames of the dataset trained on")
    ap.add_argument("--rounds", type=int, default=2, help="alternating rounds (the best is reported; with "
                                                          "--precision, the median)")
    ap.add_argument("--families", default=None, help=f"of {', '.join(FAMILIES)} (default: all; with --precision, "
                                                     "alexnet,mobilenet-h1)")
    ap.add_argument("--before-tree", type=Path, help="run the first configuration from this checkout")
    ap.add_argument("--precision", dest="compare", action="store_const", const="precision",
                    help="float32 against bfloat16 autocast instead")
    ap.add_argument("--allocator", dest="compare", action="store_const", const="allocator",
                    help="glibc's default allocator against freed memory kept (core/allocator.py) instead")
    ap.add_argument("--input", dest="compare", action="store_const", const="input",
                    help="the input path in tensor code against the compiled one (perception/input_kernels.py) "
                         "instead")
    both = "--precision, --allocator, --input"
    ap.add_argument("--threads", type=int, help=f"{both}: threads of each training (default: torch's)")
    ap.add_argument("--side-by-side", type=int, default=1, help=f"{both}: trainings at once in each setting")
    ap.add_argument("--iterations", type=int, help=f"{both}: iterations of each training (default: the family's)")
    ap.add_argument("--data", type=Path, help=f"{both}: train on this dataset (say, a recipe's, with its frame cache) "
                                               "instead of generating --frames")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    if args.before_tree is not None and not (args.before_tree / "drivestudio" / "__main__.py").is_file():
        ap.error(f"--before-tree: {args.before_tree} is not a checkout of this project")
    if args.side_by_side < 1 or (args.iterations is not None and args.iterations < 2):
        ap.error("--side-by-side must be at least 1 and --iterations at least 2")
    if (args.side_by_side != 1 or args.iterations is not None) and not args.compare:
        ap.error("--side-by-side and --iterations go with --precision, --allocator or --input")
    if args.data is not None and not (args.compare and (args.data / "manifest.json").is_file()):
        ap.error("--data goes with --precision, --allocator or --input, and names a dataset folder")
    if args.compare and args.before_tree is not None:
        ap.error(f"--{args.compare} compares two settings of this checkout: leave out --before-tree")
    if args.families is None:
        args.families = "alexnet,mobilenet-h1" if args.compare else ",".join(FAMILIES)
    if args.compare:
        pair(args)
        return
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
