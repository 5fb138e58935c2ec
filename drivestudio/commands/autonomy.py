"""drivestudio autonomy --model CKPT --mode direct|furtive --seconds S [--rounds K]: MultiNet's percentage autonomy."""
from __future__ import annotations

from pathlib import Path

from controller.sidewalk.correction import RULES
from core.files import check_output_dir
from core.signals import exit_on_sigterm
from drivestudio.checkpoints import check_checkpoint_path, check_device, load_predictor_for
from drivestudio.commands.common import add_device_option, run_dir
from drivestudio.commands.numbers import count, finite, positive, seed
from drivestudio.errors import UsageError
from drivestudio.worlds.sidewalk import autonomy
from drivestudio.worlds.sidewalk.autonomy import HELD_OUT_OBSTACLES, HELD_OUT_PATH


def register(sub) -> None:
    p = sub.add_parser("autonomy", help="percentage autonomy of a sidewalk network under the expert's correction",
                       description="A trained sidewalk network (Z2Color: MultiNet or MTL) drives a held-out loop with "
                                   "obstacles in one behavioural mode while the expert watches under the correction "
                                   "rule (docs/sidewalk.md); autonomy = (1 - correction time / elapsed time) * 100, "
                                   "as in Chowdhuri, Pankaj and Zipser's MultiNet. Writes autonomy.md/.json (with the "
                                   "take-overs by the rule's clause that caused them), a video "
                                   "per round marking the corrections, and every round's steps as a dataset that "
                                   "`train` merges (--data A,B); --rounds K repeats drive, merge and retrain.")
    p.add_argument("--model", required=True, help="a sidewalk checkpoint (drivestudio train --model z2color)")
    p.add_argument("--mode", choices=("direct", "follow", "furtive"), default="direct",
                   help="behavioural mode (the paper measured direct and furtive; default direct)")
    p.add_argument("--seconds", type=positive(24 * 3600.0), default=120.0, help="simulated seconds per round (120)")
    p.add_argument("--rounds", type=count(1, 20), default=1, help="rounds of drive, merge, retrain (default 1)")
    p.add_argument("--epochs", type=count(1, 1000), default=3, help="epochs of each retraining (default 3)")
    p.add_argument("--data", help="the training data to merge the corrections with (default: the checkpoint's)")
    p.add_argument("--path", default=HELD_OUT_PATH, help=f"the loop (default {HELD_OUT_PATH}, held out of "
                                                          "generate's default plan)")
    p.add_argument("--obstacles", type=finite(0.0, 12.0), default=HELD_OUT_OBSTACLES,
                   help=f"obstacles per 100 m (default {HELD_OUT_OBSTACLES:g})")
    p.add_argument("--rule", choices=RULES, default="safety",
                   help="the correction rule: safety (take over for leaving the path, an imminent collision, a "
                        "stalled car; default) or strict (also for deviating from the expert)")
    p.add_argument("--seed", type=seed(), default=0, help="seed of the scene (default 0)")
    p.add_argument("--no-video", dest="video", action="store_false", help="do not write the videos")
    add_device_option(p)
    p.add_argument("--out", help="folder for the results (default runs/autonomy-TIME)")
    p.set_defaults(func=run)


def run(args) -> int:
    check_device(args.device)
    check_checkpoint_path(args.model)
    load_predictor_for(args.model, "sidewalk", args.device)   # a model of another world: one line, before driving
    roots = autonomy.merge_roots(args.model, args.data, args.rounds)   # the retraining's data, checked now
    check_output_dir(args.out or "runs")
    if args.out is not None and autonomy.earlier_run(Path(args.out)):
        raise UsageError(f"--out {args.out} holds an earlier autonomy run "
                         f"({', '.join(autonomy.earlier_run(Path(args.out)))}); give another folder")
    out = run_dir(args.out, "autonomy")
    autonomy.check_outputs(out, args.rounds, args.video)    # every file a round writes, checked now
    drive = autonomy.Drive(args.model, args.mode, args.seconds, args.path, args.obstacles, args.seed, args.rule,
                           args.device, args.video)
    with exit_on_sigterm():   # a SIGTERM ends the round in order: autonomy.json says the run is incomplete
        results = autonomy.run(drive, out, args.rounds, args.epochs, roots)
    print(autonomy.write_summary(out, results, args.mode, complete=True))
    print(f"results in {out}/autonomy.md and autonomy.json")
    return 0
