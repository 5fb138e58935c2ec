"""drivestudio autonomy --model CKPT --mode direct|furtive --seconds S [--rounds K] [--set NAME=VALUE ...]:
MultiNet's percentage autonomy; its settings are those of Autonomy (drivestudio/worlds/sidewalk/autonomy.py)."""
from __future__ import annotations

from pathlib import Path

from core.files import check_output_dir
from core.signals import exit_on_sigterm
from drivestudio.checkpoints import check_checkpoint_path, check_device, load_predictor_for
from drivestudio.commands.common import run_dir
from drivestudio.commands.run_settings import add_flags, add_set, resolve
from drivestudio.errors import UsageError
from drivestudio.worlds.sidewalk import autonomy
from drivestudio.worlds.sidewalk.autonomy import Autonomy

# the settings most runs give; every other one is --set NAME=VALUE
FLAGS = ("model", "mode", "seconds", "rounds", "path", "rule", "device", "out")


def register(sub) -> None:
    p = sub.add_parser("autonomy", help="percentage autonomy of a sidewalk network under the expert's correction",
                       description="A trained sidewalk network (Z2Color: MultiNet or MTL) drives a held-out loop with "
                                   "obstacles in one behavioural mode while the expert watches under the correction "
                                   "rule (docs/sidewalk.md); autonomy = (1 - correction time / elapsed time) * 100, "
                                   "as in Chowdhuri, Pankaj and Zipser's MultiNet. Writes autonomy.md/.json (with the "
                                   "take-overs by the rule's clause that caused them), a video "
                                   "per round marking the corrections, and every round's steps as a dataset that "
                                   "`train` merges (--data A,B; --set record=false for a run only measured); "
                                   "--rounds K repeats drive, merge and retrain.")
    add_flags(p, Autonomy, FLAGS)
    add_set(p, Autonomy, FLAGS, "the autonomy run")
    p.set_defaults(func=run)


def run(args) -> int:
    cfg = resolve(Autonomy(), args, FLAGS)
    autonomy.check_rounds(cfg, cfg.rounds)
    check_device(cfg.device)
    check_checkpoint_path(cfg.model)
    load_predictor_for(cfg.model, "sidewalk", cfg.device)   # a model of another world: one line, before driving
    roots = autonomy.merge_roots(cfg.model, cfg.data, cfg.rounds)   # the retraining's data, checked now
    check_output_dir(cfg.out or "runs")
    if cfg.out is not None and autonomy.earlier_run(Path(cfg.out)):
        raise UsageError(f"--out {cfg.out} holds an earlier autonomy run "
                         f"({', '.join(autonomy.earlier_run(Path(cfg.out)))}); give another folder")
    out = run_dir(cfg.out, "autonomy")
    autonomy.check_outputs(out, cfg.rounds, cfg.video)    # every file a round writes, checked now
    with exit_on_sigterm():   # a SIGTERM ends the round in order: autonomy.json says the run is incomplete
        results = autonomy.run(cfg, out, cfg.rounds, cfg.epochs, roots)
    print(autonomy.write_summary(out, results, cfg.mode, complete=True))
    print(f"results in {out}/autonomy.md and autonomy.json")
    return 0
