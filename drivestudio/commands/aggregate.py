"""drivestudio aggregate --data DIR --model CKPT --out DIR [--set NAME=VALUE ...]: closed-loop data aggregation
(DAgger) rounds for a highway model (docs/aggregation.md); its settings are AggregationConfig's."""
from __future__ import annotations

import sys
from pathlib import Path

from core.files import check_output_dir
from drivestudio.checkpoints import check_checkpoint_path, check_device
from drivestudio.commands.run_settings import add_config, add_flags, add_set, resolve
from drivestudio.errors import UsageError
from drivestudio.worlds.highway.aggregation_config import AggregationConfig
from perception.memory import check_batch

# the settings most runs give; every other one is --set NAME=VALUE
FLAGS = ("data", "model", "out", "rounds", "suite", "workers", "seed", "device")


def register(sub) -> None:
    p = sub.add_parser("aggregate", help="DAgger rounds: the model drives, its visited frames get exact labels, "
                                         "the sets are merged and the model fine-tuned",
                       description="Closed-loop data aggregation with exact labels. Each round drives training "
                                   "tracks (never a benchmark route) with the expert and the model mixed step by step "
                                   "(the expert's share beta x decay^(round-1)), records every visited frame with its "
                                   "exact indicators, merges them with the expert dataset and fine-tunes the model "
                                   "from its checkpoint. At the end one benchmark drives every round's model. "
                                   "Running the same command again (or --config with the run's config.json) "
                                   "continues an interrupted run.")
    add_flags(p, AggregationConfig, FLAGS, config=True)
    add_set(p, AggregationConfig, FLAGS, "the aggregation run")
    add_config(p, "an aggregation")
    p.set_defaults(func=run)


def run(args) -> int:
    from perception.checkpoint import load_checkpoint  # lazy: torch
    from perception.shards import Dataset  # lazy: pyarrow

    cfg = resolve(AggregationConfig(), args, FLAGS)
    check_device(cfg.device)
    check_output_dir(cfg.out, "aggregation folder")
    check_checkpoint_path(cfg.model)
    spec = load_checkpoint(cfg.model, world="highway")["spec"]
    if cfg.batch_size is not None:
        check_batch(cfg.batch_size, spec["input"])   # before a batch is allocated
    if Dataset(Path(cfg.data)).world != "highway":
        raise UsageError(f"--data {cfg.data} is a dataset of the {Dataset(Path(cfg.data)).world} world; "
                         "aggregation rounds are the highway's")
    if cfg.suite not in ("none", "default"):
        # lazy: the benchmark, only when it runs (not for --help)
        from drivestudio.worlds.highway.benchmark import load_suite
        load_suite(cfg.suite)   # a bad suite fails now, not after the rounds
    from drivestudio.worlds.highway.aggregation import Aggregation  # lazy: torch, SUMO

    try:
        state = Aggregation(cfg).run()
    except KeyboardInterrupt:
        print("drivestudio aggregate: interrupted; run the same command again to continue", file=sys.stderr)
        return 130
    print((Path(cfg.out) / "aggregation.md").read_text())
    print(f"rounds, merged datasets and models in {cfg.out}/; {len(state['rounds'])} round(s) done")
    return 0
