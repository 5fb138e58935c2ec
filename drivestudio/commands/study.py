"""drivestudio study --out DIR [--quick] [--set NAME=VALUE ...]: the MultiNet study in one command
(drivestudio/worlds/sidewalk/study.py); its settings are StudyConfig's."""
from __future__ import annotations

from dataclasses import replace

from core.conditions import SEEDED, names
from core.files import check_output_dir
from core.signals import exit_on_sigterm
from drivestudio.checkpoints import check_device
from drivestudio.commands.run_settings import add_config, add_flags, add_set, resolve
from drivestudio.errors import UsageError
from drivestudio.worlds.sidewalk.study import PAPER_SCALE, QUICK, ROUND_LOOPS, Study, StudyConfig
from sim.sidewalk.errors import PathError
from sim.sidewalk.paths import load_path

# the settings most runs give; every other one is --set NAME=VALUE
FLAGS = ("out", "seed", "jobs", "device")


def register(sub) -> None:
    p = sub.add_parser("study", help="the MultiNet study: data, MultiNet and MTL nets, Figures 7 and 8, correction "
                                     "rounds, percentage autonomy",
                       description="Chowdhuri, Pankaj and Zipser's MultiNet study in simulation, in one command: a "
                                   "balanced sidewalk data set, MultiNet and the three MTL nets trained in several "
                                   "trials, Figures 7 and 8, correction rounds (DAgger) and percentage autonomy on "
                                   "held-out loops under both correction rules; STUDY.md, study.json and config.json "
                                   "in --out. Running the same command again (or --config with the study's "
                                   "config.json) continues a study that was cut off. With --device cuda the defaults "
                                   "are the paper's: " + ", ".join(f"{k}={v}" for k, v in PAPER_SCALE.items()) +
                                   " (docs/results.md).")
    p.add_argument("--quick", action="store_true",
                   help="a tiny study (3-4 minutes), as the tests run it: " +
                        ", ".join(f"{k}={v}" for k, v in QUICK.items()))
    add_flags(p, StudyConfig, FLAGS, config=True)
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="the verbs as local processes (default), or as Ray tasks on the cluster of RAY_ADDRESS (pip "
                        "install 'drivestudio[cluster]'; --out must be a path every node shares; --jobs does not "
                        "apply; docs/scaling.md)")
    add_set(p, StudyConfig, FLAGS, "the study")
    add_config(p, "a study")
    p.set_defaults(func=run)


def study_config(args) -> StudyConfig:
    """The study's settings: the defaults (--quick's, or on a GPU the paper's epochs and trials), then the --config
    file's, the options given and every --set."""
    if args.quick and args.config:
        raise UsageError(f"--quick: {args.config} holds every setting of its study; give one of the two")
    cfg = resolve(replace(StudyConfig(), **QUICK) if args.quick else StudyConfig(), args, FLAGS)
    if not args.quick and cfg.device.startswith("cuda"):
        cfg = resolve(replace(StudyConfig(), **PAPER_SCALE), args, FLAGS)
    return cfg


def check_loops(cfg: StudyConfig) -> None:
    """Autonomy is measured on loops that are there and held out of the study's data and rounds."""
    if not cfg.loop_names:
        raise UsageError("loops names no loop")
    for loop in cfg.loop_names:
        try:
            load_path(loop)
        except PathError as e:
            raise UsageError(f"loops: {e}") from None
        if loop in ROUND_LOOPS or loop in [f"procedural:{cfg.seed * 1000 + i}" for i in range(cfg.procedural)]:
            raise UsageError(f"loops: {loop} is driven by the study's data or rounds; autonomy is measured on "
                             "held-out loops only")


def check_conditions(cfg: StudyConfig) -> None:
    """New conditions are new to the networks: none is one the data or the rounds are drawn in. The seeded look's
    times of day are conditions too (noon, morning and afternoon are clear, evening is low_sun, overcast is
    overcast), so with the seeded look only night, fog and rain are held out."""
    from sim.sidewalk.conditions import CONDITION_OF_TIME  # lazy: the painters' effects (numba), not for --help
    held = cfg.new_condition_names
    repeated = sorted({n for n in held if held.count(n) > 1})
    if repeated:
        raise UsageError(f"new_conditions names {', '.join(repeated)} more than once")
    trained = set(names(cfg.condition))
    seen = [n for n in held if n in trained]
    if seen:
        raise UsageError(f"new_conditions: {', '.join(seen)} {'is' if len(seen) == 1 else 'are'} also in "
                         f"condition={cfg.condition}; the new conditions are held out of the data and the rounds")
    seeded = [n for n in held if SEEDED in trained and n in CONDITION_OF_TIME.values()]
    if seeded:
        raise UsageError(f"new_conditions: the seeded look of condition={cfg.condition} draws {', '.join(seeded)} "
                         "among its times of day; hold out night, fog or rain, or name the training conditions "
                         "(--set condition=clear,overcast,night,rain)")


def run(args) -> int:
    cfg = study_config(args)
    check_device(cfg.device)
    check_output_dir(cfg.out)
    check_loops(cfg)
    check_conditions(cfg)
    with exit_on_sigterm():   # a SIGTERM ends the running verbs too, each keeping what it finished
        report = Study(cfg, backend=args.backend).run()
    print(f"the study's report is {report}")
    return 0
