"""drivestudio study --out DIR [--quick]: the MultiNet study in one command (drivestudio/worlds/sidewalk/study.py)."""
from __future__ import annotations

from controller.sidewalk.correction import RULES
from core.files import check_output_dir
from core.signals import exit_on_sigterm
from drivestudio.checkpoints import check_device
from drivestudio.commands.common import add_device_option
from drivestudio.commands.numbers import count, finite, positive, seed
from drivestudio.errors import UsageError
from drivestudio.worlds.sidewalk.study import ROUND_LOOPS, Study, StudyConfig, config_from_args
from sim.sidewalk.errors import PathError
from sim.sidewalk.paths import load_path


def register(sub) -> None:
    d = StudyConfig()
    p = sub.add_parser("study", help="the MultiNet study: data, MultiNet and MTL nets, Figures 7 and 8, correction "
                                     "rounds, percentage autonomy",
                       description="Chowdhuri, Pankaj and Zipser's MultiNet study in simulation, in one command: a "
                                   "balanced sidewalk data set, MultiNet and the three MTL nets trained in several "
                                   "trials, Figures 7 and 8, correction rounds (DAgger) and percentage autonomy on "
                                   "held-out loops under both correction rules; STUDY.md and study.json in --out. "
                                   "Running the same command again continues a study that was cut off. With "
                                   "--device cuda the defaults are the paper's 24 epochs and 8 trials "
                                   "(docs/results.md).")
    p.add_argument("--out", default=d.out, help=f"folder of the study (default {d.out})")
    p.add_argument("--quick", action="store_true", help="a tiny study (3-4 minutes), as the tests run it")
    p.add_argument("--moments", type=count(100, 10**8), help=f"data moments at least (default {d.moments:,})")
    p.add_argument("--episode-frames", type=count(20, 10**5), help=f"steps per episode (default {d.episode_frames})")
    p.add_argument("--procedural", type=count(0, 1000),
                   help=f"procedural loops beside the presets (default {d.procedural})")
    p.add_argument("--perturbed", type=finite(0.0, 1.0),
                   help=f"share of the data's episodes whose expert is knocked aside now and then, its recoveries "
                        f"labelled (default {d.perturbed:g}; docs/sidewalk.md)")
    p.add_argument("--epochs", type=count(1, 1000), help=f"epochs per trial (default {d.epochs})")
    p.add_argument("--trials", type=count(1, 100), help=f"trials per network (default {d.trials})")
    p.add_argument("--batch-size", type=count(3, 65536), help=f"moments per batch (default {d.batch_size})")
    p.add_argument("--steer-share", type=finite(0.0, 1.0), metavar="F",
                   help=f"share of each mode's draws from its steering moments in every training (default "
                        f"{d.steer_share:g}; train --steer-share)")
    p.add_argument("--rounds", type=count(1, 20), help=f"correction rounds before the final autonomy runs (default "
                                                       f"{d.rounds})")
    p.add_argument("--round-seconds", type=positive(24 * 3600.0),
                   help=f"simulated seconds each network drives per mode and round (default {d.round_seconds:g})")
    p.add_argument("--round-epochs", type=count(1, 1000), help=f"fine-tuning epochs per round (default "
                                                               f"{d.round_epochs})")
    p.add_argument("--round-moments", type=count(0, 10**9),
                   help=f"moments of each mode an epoch of a round's fine-tuning draws from the data and every "
                        f"round's recordings, 0 for all of them (default {d.round_moments})")
    p.add_argument("--loops", help=f"held-out loops of the autonomy runs (default {','.join(d.loops)})")
    p.add_argument("--runs", type=count(1, 1000), help=f"autonomy runs per loop (default {d.runs})")
    p.add_argument("--autonomy-seconds", type=positive(24 * 3600.0),
                   help=f"simulated seconds per autonomy run (default {d.autonomy_seconds:g})")
    p.add_argument("--baseline-runs", type=count(0, 1000),
                   help=f"autonomy runs per loop before the rounds, 0 for none (default {d.baseline_runs})")
    p.add_argument("--rule", choices=RULES, help="the correction rule of the rounds and the headline (default "
                                                 "safety); the final runs measure both")
    p.add_argument("--seed", type=seed(), help="seed of the data, the trials and the runs (default 0)")
    p.add_argument("--jobs", type=count(1, 64), help=f"trainings and autonomy runs side by side, each with cores / "
                                                     f"jobs threads (default {d.jobs})")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="the verbs as local processes (default), or as Ray tasks on the cluster of RAY_ADDRESS (pip "
                        "install 'drivestudio[cluster]'; --out must be a path every node shares; --jobs does not "
                        "apply; docs/scaling.md)")
    add_device_option(p, default="cpu")
    p.set_defaults(func=run)


def run(args) -> int:
    check_device(args.device)
    check_output_dir(args.out)
    cfg = config_from_args(args)
    if not cfg.loops:
        raise UsageError("--loops names no loop")
    for loop in cfg.loops:
        try:
            load_path(loop)
        except PathError as e:
            raise UsageError(f"--loops: {e}") from None
        if loop in ROUND_LOOPS or loop in [f"procedural:{cfg.seed * 1000 + i}" for i in range(cfg.procedural)]:
            raise UsageError(f"--loops: {loop} is driven by the study's data or rounds; autonomy is measured on "
                             "held-out loops only")
    with exit_on_sigterm():   # a SIGTERM ends the running verbs too, each keeping what it finished
        report = Study(cfg, backend=args.backend).run()
    print(f"the study's report is {report}")
    return 0
