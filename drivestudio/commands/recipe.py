"""drivestudio recipe: from nothing to the best learned highway driver in one command (docs/aggregation.md):
a dataset of the expert, a MobileNet with the previous frame, data-aggregation rounds, and the benchmark of every
round beside the oracle, ending with the leaderboard. Each step continues where an interrupted run stopped."""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

from core.files import check_output_dir, make_dir
from drivestudio.cli import main
from drivestudio.errors import UsageError
from drivestudio.numbers import count
from drivestudio.outputs import write_text


@dataclass(frozen=True)
class Size:
    frames: int = 20000          # the expert dataset
    iterations: int = 6000       # the first training
    rounds: int = 3              # aggregation rounds
    round_frames: int = 4000
    round_iterations: int = 1500
    history: int = 1             # earlier frames the model reads
    emphasis: int = 4            # an epoch shows each decisive frame this often (docs/aggregation.md)


FULL = Size()
QUICK = Size(frames=400, iterations=20, rounds=1, round_frames=60, round_iterations=4)


def register(sub) -> None:
    p = sub.add_parser("recipe", help="from nothing to the best learned highway driver: generate, train, "
                                      "aggregation rounds, benchmark",
                       description="Generate the expert dataset, train a MobileNet that reads the previous frame too, "
                                   "run data-aggregation rounds (the model drives, its frames get exact labels, it is "
                                   "fine-tuned), then benchmark every round's model beside the oracle on the "
                                   "held-out suite. About 50 minutes on a 2-core CPU, timed as one run "
                                   "(docs/aggregation.md); running "
                                   "the same command again continues where it stopped.")
    p.add_argument("--out", default="out/recipe", help="output folder (default out/recipe)")
    p.add_argument("--quick", action="store_true", help="every step at its smallest (what the tests run)")
    p.add_argument("--frames", type=count(200, 10**7), default=None, help=f"expert frames (default {FULL.frames})")
    p.add_argument("--iterations", type=count(1, 10**7), default=None,
                   help=f"iterations of the first training (default {FULL.iterations})")
    p.add_argument("--rounds", type=count(1, 50), default=None, help=f"aggregation rounds (default {FULL.rounds})")
    p.add_argument("--emphasis", type=count(1, 100), default=None,
                   help=f"times every epoch shows a decisive frame (a car closer than 20 m ahead in the host's or a "
                        f"neighbouring lane), in the first training and the rounds (default {FULL.emphasis})")
    p.add_argument("--suite", default="default", help="the benchmark suite (default: the held-out default suite)")
    p.add_argument("--workers", type=count(1, 256), default=2, help="worker processes (default 2)")
    p.set_defaults(func=run)


def run(args) -> int:
    size = QUICK if args.quick else FULL
    size = replace(size, **{k: v for k, v in (("frames", args.frames), ("iterations", args.iterations),
                                               ("rounds", args.rounds), ("emphasis", args.emphasis))
                                   if v is not None})
    out = make_dir(check_output_dir(args.out))
    if args.suite not in ("default", "none") and not Path(args.suite).is_file():
        raise UsageError(f"--suite: no such file: {args.suite}")
    t_start = time.perf_counter()
    log: list[str] = []

    def step(title: str, *argv) -> None:
        t0 = time.perf_counter()
        print(f"\n== {title}  ({(time.perf_counter() - t_start) / 60:.1f} min so far)\n"
              f"$ drivestudio {' '.join(map(str, argv))}", flush=True)
        log.append("drivestudio " + " ".join(map(str, argv)))
        rc = main([str(a) for a in argv])
        if rc != 0:
            raise SystemExit(rc)
        print(f"({(time.perf_counter() - t0) / 60:.1f} min)", flush=True)

    data, model = out / "data", out / "mobilenet.pt"
    step(f"the expert's dataset: {size.frames} frames", "generate", "--out", data, "--frames", size.frames,
         "--workers", args.workers, "--quiet")
    step(f"a MobileNet reading the previous frame too: {size.iterations} iterations", "train", "--data", data,
         "--model", "mobilenet", "--history", size.history, "--out", model, "--iterations", size.iterations,
         "--val-every", max(10, size.iterations // 6), "--workers", 0, "--device", "cpu",
         "--emphasis", size.emphasis)
    step(f"{size.rounds} aggregation round(s) of {size.round_frames} frames, then the benchmark", "aggregate",
         "--data", data, "--model", model, "--out", out / "aggregation", "--rounds", size.rounds, "--frames",
         size.round_frames, "--iterations", size.round_iterations, "--emphasis", size.emphasis, "--suite", args.suite,
         "--workers", args.workers)
    minutes = (time.perf_counter() - t_start) / 60
    write_text(out / "commands.txt", "\n".join(log) + "\n")
    print(f"\nrecipe done in {minutes:.1f} min (this run); the leaderboard: {out / 'aggregation' / 'benchmark'}/"
          f"leaderboard.md; rounds: {out / 'aggregation' / 'aggregation.md'}")
    return 0
