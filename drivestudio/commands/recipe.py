"""drivestudio recipe: from nothing to the best learned highway driver in one command (docs/aggregation.md):
a dataset of the expert, three MobileNets with the previous frame trained side by side from three seeds, their
ensemble with the pass memory, and the benchmark of every member and the ensemble beside the oracle, ending with
the leaderboard. `--set members=1 --set rounds=N` trains one network and runs N data-aggregation rounds instead.
`--extended` is the recipe of the extended label set's best driver (drivestudio/commands/recipe_extended.py).
Each step continues where an interrupted run stopped."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from core.files import check_output_dir, make_dir
from core.settings import as_json, entries, setting
from drivestudio.commands.recipe_extended import EXTENDED, EXTENDED_QUICK, Extended, extended_recipe
from drivestudio.commands.recipe_steps import RecipePlan, Steps, benchmark, ensemble_step, fingerprints, training_plan
from drivestudio.commands.run_settings import add_config, add_flags, add_set, defaults_text, read_config, resolve
from drivestudio.errors import UsageError
from drivestudio.outputs import write_json, write_text
from drivestudio.worlds.highway.filters import MAX_MEMORY


@dataclass(frozen=True)
class Size(RecipePlan):
    frames: int = setting(20000, "expert frames", low=200, high=10**7)
    iterations: int = setting(6000, "iterations of each network's training", low=1, high=10**7)
    members: int = setting(3, "networks trained side by side (seeds 0, 1, ...), one thread each, and driven as one "
                              "ensemble; 1: a single network", low=1, high=8)
    # docs/controller.md; chosen on the design suites
    pass_memory: float = setting(15.0, "the ensemble's pass memory", unit="s", low=0.0, high=MAX_MEMORY)
    rounds: int = setting(0, "data-aggregation rounds after the training (members=1 only)", low=0, high=50)
    round_frames: int = setting(4000, "frames each aggregation round drives", low=20, high=10**7)
    round_iterations: int = setting(1500, "fine-tuning iterations of each aggregation round", low=1, high=10**7)
    history: int = setting(1, "earlier frames each network reads", low=0, high=2)
    # docs/aggregation.md, emphasis on the decisive frames
    emphasis: int = setting(4, "times every epoch shows a decisive frame (a car closer than 20 m ahead in the host's "
                               "or a neighbouring lane), in the trainings and the rounds", low=1, high=100)


FULL = Size()
QUICK = Size(frames=400, iterations=20, members=2, round_frames=60, round_iterations=4)
FLAGS = ("out", "suite", "workers")   # the settings most runs give; every other one is --set NAME=VALUE
RECIPES = {"ensemble": Size, "extended": Extended}   # config.json's "recipe"


def register(sub) -> None:
    p = sub.add_parser("recipe", help="from nothing to the best learned highway driver: generate, train an "
                                      "ensemble, benchmark",
                       description="Generate the expert dataset, train three MobileNets that read the previous frame "
                                   "too side by side (seeds 0, 1, 2), make them one ensemble with the pass memory, "
                                   "then benchmark every member and the ensemble beside the oracle on the held-out "
                                   "suite. About an hour on a 2-core CPU, timed as one run (docs/aggregation.md); "
                                   "running the same command again (or --config with the recipe's config.json) "
                                   "continues where it stopped. --set members=1 --set rounds=N trains one network "
                                   "and runs N data-aggregation rounds instead.")
    p.add_argument("--quick", action="store_true", help="every step at its smallest (what the tests run)")
    p.add_argument("--extended", action="store_true",
                   help="the extended label set's driver instead: two networks of the paper's 13 (members) and one "
                        "of the cars behind, all with the rear-view mirror and the side views, an aggregation round "
                        "(rounds) for each forward network, their ensemble with the lookout controller; 27-79 "
                        "minutes by the CPU")
    add_flags(p, Size, FLAGS, config=True)
    add_set(p, Size, FLAGS, "the recipe", listing=f"{defaults_text(Size, FLAGS)}; with --extended "
            f"{defaults_text(Extended, FLAGS)}")
    add_config(p, "the recipe")
    p.set_defaults(func=run)


def recipe_config(args) -> Size | Extended:
    """The recipe's settings: its preset (--extended, --quick), then the --config file's, the options given and
    every --set; refuses rounds with an ensemble (but for --extended, whose rounds fine-tune each forward network)."""
    saved = read_config(args.config, ("recipe", "settings")) if args.config else {}
    if saved.get("recipe", "ensemble") not in RECIPES or not isinstance(saved.get("settings", {}), dict):
        raise UsageError(f"{args.config}: a recipe's configuration is {{\"recipe\": {' or '.join(RECIPES)}, "
                         "\"settings\": {...}}")
    if args.quick and args.config:
        raise UsageError(f"--quick: {args.config} holds every setting of its recipe; give one of the two")
    if args.extended and args.config and saved.get("recipe") != "extended":
        raise UsageError(f"--extended: {args.config} configures the {saved.get('recipe', 'ensemble')} recipe")
    extended = args.extended or saved.get("recipe") == "extended"
    if not extended:
        for pair in args.set or ():
            if pair.partition("=")[0].strip() in set(entries(Extended)) - set(entries(Size)):
                raise UsageError(f"--set {pair}: a setting of the extended recipe; give --extended too")
    base = (EXTENDED_QUICK if args.quick else EXTENDED) if extended else QUICK if args.quick else FULL
    size = resolve(base, args, FLAGS, saved.get("settings", {}) if args.config else None)
    if isinstance(size, Size) and size.rounds and size.members > 1:
        raise UsageError(f"rounds={size.rounds} needs members=1: an aggregation round fine-tunes one network, and the "
                         f"recipe trains {size.members}")
    return size


def run(args) -> int:
    size = recipe_config(args)
    if size.suite not in ("default", "none"):
        from drivestudio.worlds.highway.benchmark import load_suite  # the world's benchmark: only when asked
        load_suite(size.suite)   # a bad suite fails now, not after an hour of training
    plan = training_plan(size)   # likewise a bad protocol, condition or track list
    out = make_dir(check_output_dir(size.out))
    # what `drivestudio recipe --config` runs again
    write_json(out / "config.json", {"recipe": "extended" if isinstance(size, Extended) else "ensemble",
                                     "settings": as_json(size)})
    steps = Steps(out)
    if isinstance(size, Extended):
        board = extended_recipe(steps, size, plan)
    else:
        data = out / "data"
        steps.verb(f"the expert's dataset: {size.frames} frames", "generate", "--out", data, "--frames",
                   size.frames, *plan, "--workers", size.workers)
        board = ensemble_recipe(steps, size, data) if size.members > 1 else single_recipe(steps, size, data)
    fingerprints(steps)
    write_text(out / "commands.txt", "\n".join(steps.log) + "\n")
    print(f"\nrecipe done in {steps.minutes():.1f} min (this run); " +
          (f"the leaderboard: {board}" if board else f"the models are in {out} (no benchmark: --suite none)"))
    return 0


def train_argv(size: Size, data: Path, model: Path, seed: int = 0) -> list:
    return ["train", "--data", data, "--model", "mobilenet", "--set", f"history={size.history}", "--out", model,
            "--iterations", size.iterations, "--set", f"val_every={max(10, size.iterations // 6)}", "--workers", 0,
            "--device", "cpu", "--set", f"emphasis={size.emphasis}", "--seed", seed]


def single_recipe(steps: Steps, size: Size, data: Path) -> Path | None:
    """One network, then `size.rounds` aggregation rounds with their benchmark (or the benchmark alone)."""
    model = steps.out / "mobilenet.pt"
    steps.verb(f"a MobileNet reading the previous frame too: {size.iterations} iterations",
               *train_argv(size, data, model))
    if size.rounds:
        agg = steps.out / "aggregation"
        steps.verb(f"{size.rounds} aggregation round(s) of {size.round_frames} frames, then the benchmark",
                   "aggregate", "--data", data, "--model", model, "--out", agg, "--rounds", size.rounds,
                   "--set", f"frames={size.round_frames}", "--set", f"iterations={size.round_iterations}", "--set",
                   f"emphasis={size.emphasis}", "--suite", size.suite, "--workers", size.workers)
        return None if size.suite == "none" else agg / "benchmark" / "leaderboard.md"
    return benchmark(steps, [model], size)


def ensemble_recipe(steps: Steps, size: Size, data: Path) -> Path | None:
    """`size.members` networks trained side by side from seeds 0, 1, ..., one ensemble of them, its benchmark."""
    from perception.frame_cache import prepare_cache  # torch: only once the recipe runs
    from perception.shards import Dataset  # pyarrow: only once the recipe runs

    t0 = steps.header("the frame cache, decoded once for every member", [])
    dataset = Dataset(data)
    prepare_cache(dataset, dataset.select("train"))   # before the members: they would race to write it
    steps.done(t0)
    members = [steps.out / f"member-{k}.pt" for k in range(size.members)]
    steps.side_by_side(f"{size.members} MobileNets reading the previous frame too, {size.iterations} iterations "
                       f"each, side by side", [train_argv(size, data, m, seed=k) for k, m in enumerate(members)],
                       [m.with_suffix(".log") for m in members])
    ensemble = steps.out / "ensemble.pt"
    ensemble_step(steps, "the ensemble: the closest gap any member reads, the mean of everything else", members,
                  ensemble)
    return benchmark(steps, [*members, f"{ensemble}@pass_memory={size.pass_memory:g}"], size)
