"""drivestudio aggregate --data DIR --model CKPT --out DIR: closed-loop data aggregation (DAgger) rounds for a
highway model (docs/aggregation.md)."""
from __future__ import annotations

import os
import sys
from pathlib import Path

from core.files import check_output_dir
from drivestudio.checkpoints import check_checkpoint_path, check_device
from drivestudio.commands.common import add_device_option
from drivestudio.commands.numbers import count, finite, seed
from drivestudio.errors import UsageError
from perception.memory import check_batch


def register(sub) -> None:
    p = sub.add_parser("aggregate", help="DAgger rounds: the model drives, its visited frames get exact labels, "
                                         "the sets are merged and the model fine-tuned",
                       description="Closed-loop data aggregation with exact labels. Each round drives training "
                                   "tracks (never a benchmark route) with the expert and the model mixed step by step "
                                   "(the expert's share beta x decay^(round-1)), records every visited frame with its "
                                   "exact indicators, merges them with the expert dataset and fine-tunes the model "
                                   "from its checkpoint. At the end one benchmark drives every round's model. "
                                   "Running the same command again continues an interrupted run.")
    p.add_argument("--data", required=True, help="the expert dataset the model was trained on")
    p.add_argument("--model", required=True, metavar="CKPT", help="the model to start from (a highway checkpoint)")
    p.add_argument("--out", required=True, help="the run's folder (rounds, merged datasets, models, benchmark)")
    p.add_argument("--rounds", type=count(1, 50), default=3, help="aggregation rounds (default 3)")
    p.add_argument("--frames", type=count(20, 10**7), default=4000, help="frames driven per round (default 4000)")
    p.add_argument("--beta", type=finite(0.0, 1.0), default=0.5,
                   help="the expert's share of the steps in round 1 (default 0.5)")
    p.add_argument("--decay", type=finite(0.0, 1.0), default=0.5,
                   help="the expert's share shrinks by this factor per round (default 0.5)")
    p.add_argument("--iterations", type=count(1, 10**7), default=2000,
                   help="fine-tuning iterations per round (default 2000)")
    p.add_argument("--emphasis", type=count(1, 100), default=1, metavar="W",
                   help="the rounds' fine-tuning shows the decisive frames (a car closer than 20 m ahead in the "
                        "host's or a neighbouring lane) W times an epoch (default 1: as recorded; train --emphasis)")
    p.add_argument("--batch-size", type=count(1, 4096), default=None, help="default: the model family's")
    p.add_argument("--lr", type=finite(1e-9, 10.0), default=None, help="default: the model family's")
    p.add_argument("--cars", default="12-40", help="AI cars per episode, A-B (default 12-40)")
    p.add_argument("--episode-frames", type=count(20, 10**6), default=200, help="steps per episode (default 200)")
    p.add_argument("--suite", default="default",
                   help="the benchmark suite every round's model drives at the end ('none': no benchmark)")
    p.add_argument("--workers", type=count(1, 256), default=os.cpu_count() or 1,
                   help="worker processes driving episodes and routes (default: cores)")
    p.add_argument("--seed", type=seed(), default=0, help="seed of the rounds' traffic and mixing")
    add_device_option(p)
    p.set_defaults(func=run)


def _cars(text: str) -> tuple[int, int]:
    lo, _, hi = text.partition("-")
    try:
        a, b = int(lo), int(hi or lo)
    except ValueError:
        raise UsageError(f"--cars: expected N or A-B, got {text!r}") from None
    if not 0 <= a <= b <= 300:
        raise UsageError("--cars must be from 0 to 300 (and A <= B)")
    return a, b


def run(args) -> int:
    from perception.checkpoint import load_checkpoint  # lazy: torch
    from perception.shards import Dataset  # lazy: pyarrow

    check_device(args.device)
    check_output_dir(args.out, "aggregation folder")
    check_checkpoint_path(args.model)
    spec = load_checkpoint(args.model, world="highway")["spec"]
    if args.batch_size is not None:
        check_batch(args.batch_size, spec["input"])   # before a batch is allocated
    if Dataset(Path(args.data)).world != "highway":
        raise UsageError(f"--data {args.data} is a dataset of the {Dataset(Path(args.data)).world} world; "
                         "aggregation rounds are the highway's")
    suite = None if args.suite == "none" else args.suite
    if suite not in (None, "default"):
        # lazy: the benchmark, only when it runs (not for --help)
        from drivestudio.worlds.highway.benchmark import load_suite
        load_suite(suite)   # a bad suite fails now, not after the rounds
    from drivestudio.worlds.highway.aggregation import Aggregation, AggregationConfig  # lazy: torch, SUMO

    cfg = AggregationConfig(data=args.data, model=args.model, out=args.out, rounds=args.rounds, frames=args.frames,
                            beta=args.beta, decay=args.decay, iterations=args.iterations,
                            batch_size=args.batch_size, lr=args.lr, emphasis=args.emphasis,
                            episode_frames=args.episode_frames,
                            cars=_cars(args.cars), seed=args.seed, workers=args.workers, device=args.device,
                            benchmark=suite)
    try:
        state = Aggregation(cfg).run()
    except KeyboardInterrupt:
        print("drivestudio aggregate: interrupted; run the same command again to continue", file=sys.stderr)
        return 130
    print((Path(args.out) / "aggregation.md").read_text())
    print(f"rounds, merged datasets and models in {args.out}/; {len(state['rounds'])} round(s) done")
    return 0
