"""drivestudio recipe: from nothing to the best learned highway driver in one command (docs/aggregation.md):
a dataset of the expert, three MobileNets with the previous frame trained side by side from three seeds, their
ensemble with the pass memory, and the benchmark of every member and the ensemble beside the oracle, ending with
the leaderboard. `--members 1 --rounds N` is the recipe as it was: one network and N data-aggregation rounds.
`--extended` is the recipe of the extended label set's best driver (drivestudio/commands/recipe_extended.py).
Each step continues where an interrupted run stopped."""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from core.files import check_output_dir, make_dir
from drivestudio.commands.numbers import count
from drivestudio.commands.recipe_extended import EXTENDED, EXTENDED_QUICK, Extended, extended_recipe
from drivestudio.commands.recipe_steps import Steps, benchmark, ensemble_step, fingerprints
from drivestudio.errors import UsageError
from drivestudio.outputs import write_text


@dataclass(frozen=True)
class Size:
    frames: int = 20000          # the expert dataset
    iterations: int = 6000       # each network's training
    members: int = 3             # networks trained side by side (seeds 0, 1, ...) and driven as one ensemble
    pass_memory: float = 15.0    # [s] the ensemble's pass memory (docs/controller.md; chosen on the design suites)
    rounds: int = 0              # aggregation rounds (one network only)
    round_frames: int = 4000
    round_iterations: int = 1500
    history: int = 1             # earlier frames the model reads
    emphasis: int = 4            # an epoch shows each decisive frame this often (docs/aggregation.md)


FULL = Size()
QUICK = Size(frames=400, iterations=20, members=2, round_frames=60, round_iterations=4)


def register(sub) -> None:
    p = sub.add_parser("recipe", help="from nothing to the best learned highway driver: generate, train an "
                                      "ensemble, benchmark",
                       description="Generate the expert dataset, train three MobileNets that read the previous frame "
                                   "too side by side (seeds 0, 1, 2), make them one ensemble with the pass memory, "
                                   "then benchmark every member and the ensemble beside the oracle on the held-out "
                                   "suite. About an hour on a 2-core CPU, timed as one run (docs/aggregation.md); "
                                   "running the same command again continues where it stopped. --members 1 "
                                   "--rounds N trains one network and runs N data-aggregation rounds instead.")
    p.add_argument("--out", default="out/recipe", help="output folder (default out/recipe)")
    p.add_argument("--quick", action="store_true", help="every step at its smallest (what the tests run)")
    p.add_argument("--extended", action="store_true",
                   help="the extended label set's driver instead: two networks of the paper's 13 (--members) and one "
                        "of the cars behind, all with the rear-view mirror and the side views, an aggregation round "
                        "(--rounds) for each forward network, their ensemble with the lookout controller; 46-79 "
                        "minutes by the CPU")
    p.add_argument("--frames", type=count(200, 10**7), default=None, help=f"expert frames (default {FULL.frames})")
    p.add_argument("--iterations", type=count(1, 10**7), default=None,
                   help=f"iterations of each network's training (default {FULL.iterations})")
    p.add_argument("--members", type=count(1, 8), default=None,
                   help=f"networks trained side by side, one thread each, and driven as one ensemble (default "
                        f"{FULL.members}; 1: a single network)")
    p.add_argument("--rear-members", type=count(1, 4), default=None,
                   help=f"with --extended: networks of the cars behind (seeds 0, 2, ...), the nearer rear gap of "
                        f"theirs believed (default {EXTENDED.rear_members}; 2 builds one like the best driver "
                        f"measured, about 105 minutes in all, untimed)")
    p.add_argument("--no-side-views", action="store_true",
                   help="with --extended: frames with the rear-view mirror alone, without the views out of both side "
                        "windows (where a car level with the host shows; docs/rendering.md): the driver built before "
                        "them")
    p.add_argument("--rounds", type=count(1, 50), default=None,
                   help="data-aggregation rounds after the training (only with --members 1; default none)")
    p.add_argument("--emphasis", type=count(1, 100), default=None,
                   help=f"times every epoch shows a decisive frame (a car closer than 20 m ahead in the host's or a "
                        f"neighbouring lane), in the trainings and the rounds (default {FULL.emphasis})")
    p.add_argument("--suite", default="default", help="the benchmark suite (default: the held-out default suite)")
    p.add_argument("--workers", type=count(1, 256), default=2, help="worker processes (default 2)")
    p.set_defaults(func=run)


def sized(args) -> Size | Extended:
    """The recipe's size from --quick, --extended and the options given; refuses --rounds with an ensemble (but
    for --extended, whose rounds fine-tune each forward network)."""
    size: Size | Extended = (EXTENDED_QUICK if args.quick else EXTENDED) if getattr(args, "extended", False) else \
        QUICK if args.quick else FULL
    given = {k: v for k, v in (("frames", args.frames), ("iterations", args.iterations), ("members", args.members),
                               ("rear_members", args.rear_members), ("rounds", args.rounds),
                               ("emphasis", args.emphasis)) if v is not None}
    if getattr(args, "no_side_views", False):
        given["side_views"] = False
    for key, option in (("rear_members", "--rear-members"), ("side_views", "--no-side-views")):
        if key in given and not isinstance(size, Extended):
            raise UsageError(f"{option} is of the extended recipe: give --extended too")
    size = replace(size, **given)
    if isinstance(size, Size) and size.rounds and size.members > 1:
        raise UsageError(f"--rounds needs --members 1: an aggregation round fine-tunes one network, and the recipe "
                         f"trains {size.members}")
    return size


def run(args) -> int:
    size = sized(args)
    if args.suite not in ("default", "none"):
        from drivestudio.worlds.highway.benchmark import load_suite  # the world's benchmark: only when asked
        load_suite(args.suite)   # a bad suite fails now, not after an hour of training
    out = make_dir(check_output_dir(args.out))
    steps = Steps(out)
    if isinstance(size, Extended):
        board = extended_recipe(steps, size, args)
    else:
        data = out / "data"
        steps.verb(f"the expert's dataset: {size.frames} frames", "generate", "--out", data, "--frames",
                   size.frames, "--workers", args.workers, "--quiet")
        board = ensemble_recipe(steps, size, data, args) if size.members > 1 else \
            single_recipe(steps, size, data, args)
    fingerprints(steps)
    write_text(out / "commands.txt", "\n".join(steps.log) + "\n")
    print(f"\nrecipe done in {steps.minutes():.1f} min (this run); " +
          (f"the leaderboard: {board}" if board else f"the models are in {out} (no benchmark: --suite none)"))
    return 0


def train_argv(size: Size, data: Path, model: Path, seed: int = 0) -> list:
    return ["train", "--data", data, "--model", "mobilenet", "--history", size.history, "--out", model,
            "--iterations", size.iterations, "--val-every", max(10, size.iterations // 6), "--workers", 0,
            "--device", "cpu", "--emphasis", size.emphasis, "--seed", seed]


def single_recipe(steps: Steps, size: Size, data: Path, args) -> Path | None:
    """One network, then `size.rounds` aggregation rounds with their benchmark (or the benchmark alone)."""
    model = steps.out / "mobilenet.pt"
    steps.verb(f"a MobileNet reading the previous frame too: {size.iterations} iterations",
               *train_argv(size, data, model))
    if size.rounds:
        agg = steps.out / "aggregation"
        steps.verb(f"{size.rounds} aggregation round(s) of {size.round_frames} frames, then the benchmark",
                   "aggregate", "--data", data, "--model", model, "--out", agg, "--rounds", size.rounds,
                   "--frames", size.round_frames, "--iterations", size.round_iterations, "--emphasis",
                   size.emphasis, "--suite", args.suite, "--workers", args.workers)
        return None if args.suite == "none" else agg / "benchmark" / "leaderboard.md"
    return benchmark(steps, [model], args)


def ensemble_recipe(steps: Steps, size: Size, data: Path, args) -> Path | None:
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
    return benchmark(steps, [*members, f"{ensemble}@pass_memory={size.pass_memory:g}"], args)
