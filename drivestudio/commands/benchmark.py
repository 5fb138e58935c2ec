"""drivestudio benchmark: drive a suite of fixed routes with every model and rank them (docs/benchmark.md).

    benchmark --model oracle                                     the default held-out suite, the oracle alone
    benchmark --model runs/gist.pt --model runs/alexnet.pt       two checkpoints (the oracle row is always added)
    benchmark --model runs/alexnet.pt@smoothing=0.5              the controller smooths the estimates (0-0.95)
    benchmark --model runs/alexnet.pt@gap_hold=0.8               ... or holds the gaps (a closer car at once)
    benchmark --model runs/ex.pt@pass_memory=15,rear_memory=10   ... or remembers the cars out of view
    benchmark --model runs/ppo-highway.zip                       a trained policy on the exact affordances
    benchmark --suite my-suite.json --workers 2 --shm --out DIR
    benchmark --model oracle-extended --scenarios assets/scenarios   scripted scenarios: pass or fail per scenario
    benchmark --model runs/a.pt --model runs/b.pt --backend ray  every (route, model) pair a task on the Ray cluster
                                                                 of RAY_ADDRESS (docs/scaling.md)

Every route is driven with every model through drive's loop, in process (default) or with each route's driver
in its own process over shared memory (--shm); same track, traffic, seed and start for every model, so two rows
differ only by the model. Per route and overall: route completion, collisions and off-road events per km,
overtakes per km, mean speed relative to the oracle, lateral offset from the lane centre (RMS), time on markings
outside lane changes, and the driving score

    DS = route completion x 0.60^collisions x 0.65^off-road events   (per route; the suite's: the mean)

as CARLA's Driving Score. Every collision and off-road event gets a clip (OUT/clips/MODEL/ROUTE-N-EVENT-tT.mp4):
the 5 s before it and 1 s after, the box overlay of truth and estimate, the controller's state and command,
and the indicator whose error was largest in those 5 s. docs/benchmark.md defines every measure.

Writes to --out: leaderboard.md, leaderboard.csv (one row per model), routes.csv (per model and route),
leaderboard.json (everything, clips included) and clips/. The suite, the models and the output folder are
checked before anything is driven (one line and exit status 2 on bad input).

--scenarios drives scripted scenarios (docs/scenarios.md: cars placed around the host that cut in, brake, stop) as
the routes, and adds whether each model passed each one: scenarios.csv and a table in leaderboard.md. Every
collision's clip gets a scenario beside it (CLIP.scenario.json) that replays its last seconds.

A suite file: {"name": ..., "description": ..., "routes": [{"name": "r1", "track": "procedural:11", "lanes": 3,
"cars": 30, "seed": 11, "start_lane": 1, "seconds": 240}, ...]}; "track" is a preset, procedural:SEED or a
track file (relative to the suite file); "lanes" (default: the track's) and "start_lane" (0 = leftmost; default
drawn from the seed) are optional.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from core.conditions import CONDITIONS, SEEDED
from core.files import check_output, check_output_dir
from core.settings import entries, read
from drivestudio.checkpoints import check_device
from drivestudio.commands.common import add_device_option, run_dir
from drivestudio.commands.numbers import count
from drivestudio.errors import UsageError
from sim.camera import DEFAULT_RENDERER, RENDERERS
from sim.highway.config import WorldConfig


def condition_type(text: str) -> str:
    """--condition: the world configuration's setting, read and checked by it (argparse's one line on a bad name)."""
    try:
        return read(entries(WorldConfig)["condition"], text, "--condition")
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix("--condition: ")) from None


def register(sub) -> None:
    p = sub.add_parser("benchmark", help="drive fixed routes with every model and rank them by driving score",
                       description=__doc__.split("\n", 1)[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", action="append", metavar="M",
                   help="'oracle' or a highway checkpoint, optionally CKPT@smoothing=A,gap_hold=B,pass_memory=S,"
                        "rear_memory=S, or a policy (a saved Stable-Baselines3 .zip, or policy:MODULE:NAME); repeat "
                        "for more rows (default: the oracle alone; the oracle row is always added as the upper bound)")
    p.add_argument("--suite", metavar="NAME_OR_FILE",
                   help="a shipped suite by name (default, random, design, design2, controller-hard: assets/suites/) "
                        "or a suite file (default: the shipped held-out suite, default)")
    p.add_argument("--scenarios", metavar="FILE_OR_FOLDER",
                   help="scripted scenarios to drive instead of a suite: a scenario file, or a folder of them "
                        "(assets/scenarios/ ships one); pass or fail per scenario beside the driving score")
    p.add_argument("--protocol", metavar="NAME_OR_FILE",
                   help="the generalisation protocol instead of a suite: 'generalisation' (the shipped one, "
                        "assets/protocols/) or a protocol file; every cell of training and new conditions, tracks "
                        "and traffic, with the extended oracle's row beside the oracle's (protocol.md, .csv)")
    p.add_argument("--routes", help="comma-separated route names: drive only these routes of the suite")
    p.add_argument("--workers", type=count(1, 256), default=None,
                   help=f"routes driven at once, one process each (default: cores, {os.cpu_count() or 1})")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local worker processes (default), or Ray tasks on the cluster of RAY_ADDRESS (pip install "
                        "'drivestudio[cluster]'; --out and the models must be paths every node shares; --workers does "
                        "not apply)")
    p.add_argument("--shm", action="store_true",
                   help="each route's driver in its own process over shared memory, as `drive` (default: in process)")
    p.add_argument("--clips", type=count(0, 1000), default=10,
                   help="crash clips kept per route and model (default 10; 0: none)")
    p.add_argument("--renderer", choices=RENDERERS, default=DEFAULT_RENDERER, help="the renderer of the routes' frames "
                   f"(default {DEFAULT_RENDERER}; docs/rendering.md)")
    p.add_argument("--condition", type=condition_type, default=SEEDED, metavar="CONDITION[,CONDITION...]",
                   help=f"the named condition of the routes' frames, one of {', '.join(CONDITIONS)}, or several "
                   f"comma-separated that each route's seed draws one of (default {SEEDED}; docs/conditions.md)")
    add_device_option(p)
    p.add_argument("--out", help="output folder (default runs/benchmark-TIME)")
    p.set_defaults(func=run)


def run(args) -> int:
    # lazy: the benchmark loads only when it runs, not for --help
    from drivestudio.worlds.highway.benchmark import RunOptions, check_models, load_suite, run_benchmark
    from drivestudio.worlds.highway.benchmark.report import BOARD_FILES, CLIPS, write_board  # lazy: as above
    from drivestudio.worlds.highway.benchmark.scenarios import SCENARIOS_CSV, load_scenarios  # lazy: as above

    if sum(x is not None for x in (args.suite, args.scenarios, args.protocol)) > 1:
        raise UsageError("--suite, --scenarios and --protocol each name what is driven: give one")
    if args.protocol is not None:
        return run_protocol_verb(args)
    if args.out is not None:   # the folder and every file the run will write into it, before any work
        check_output_dir(args.out)
        check_output_dir(Path(args.out) / CLIPS, "clips folder")
        for name in BOARD_FILES + ((SCENARIOS_CSV,) if args.scenarios is not None else ()):
            check_output(Path(args.out) / name, None, "leaderboard file")
    check_device(args.device)
    suite = load_suite(args.suite) if args.scenarios is None else load_scenarios(args.scenarios)
    if args.routes is not None:
        names = [n.strip() for n in args.routes.split(",") if n.strip()]
        if not names:
            raise UsageError("--routes names no route")
        suite = suite.select(names)
    models = check_models(args.model)
    out = run_dir(args.out, "benchmark")
    if args.shm:   # segments of earlier benchmarks whose whole process group was killed (nobody left to clean up)
        from drivestudio.worlds.highway.benchmark.route import SHM_PREFIX  # lazy: as above
        from shm_bridge.endpoints import reclaim  # lazy: the bridge loads only when it runs, not for --help
        reclaim(SHM_PREFIX)
    opts = RunOptions(transport="shm" if args.shm else "in-process", device=args.device, renderer=args.renderer,
                      clips=args.clips, condition=args.condition)
    workers = min(args.workers or os.cpu_count() or 1, len(suite.routes) * len(models))
    print(f"benchmark: suite '{suite.name}' ({len(suite.routes)} routes, {suite.seconds / 60:.1f} simulated "
          f"minutes) x {len(models)} models ({', '.join(m.label for m in models)}), {workers} workers, "
          f"{'over shared memory' if args.shm else 'in process'}{', as Ray tasks' if args.backend == 'ray' else ''}",
          file=sys.stderr)
    board = run_benchmark(suite, models, opts, out, workers, show_progress=sys.stderr.isatty(), backend=args.backend)
    text = write_board(out, board)
    print(text.split("\n## Per route")[0].rstrip())
    clips = sum(e["overall"]["clips"] for e in board["models"])
    print(f"\n{board['run']['wall_time_s']:.0f} s with {board['run']['workers']} workers; {clips} clips; "
          f"leaderboard saved in {out}/leaderboard.md (.csv, .json)")
    return 0


def run_protocol_verb(args) -> int:
    """benchmark --protocol: every cell of the protocol, one table (protocol_run.py)."""
    from drivestudio.worlds.highway.benchmark import RunOptions, check_models, protocol_run  # lazy: as run's
    from drivestudio.worlds.highway.benchmark.protocol import load_protocol  # lazy: as above

    for flag, value in (("--routes", args.routes), ("--shm", args.shm or None), ("--condition", None
                        if args.condition == SEEDED else args.condition)):
        if value is not None:
            raise UsageError(f"{flag} does not apply to --protocol (its cells set the routes and conditions)")
    if args.out is not None:
        check_output_dir(args.out)
        for name in protocol_run.PROTOCOL_FILES:
            check_output(Path(args.out) / name, None, "protocol table")
    check_device(args.device)
    protocol = load_protocol(args.protocol)
    models = check_models(args.model)
    if "oracle-extended" not in [m.text for m in models]:
        models.insert(1, check_models(["oracle-extended"])[1])
    out = run_dir(args.out, "protocol")
    opts = RunOptions(device=args.device, renderer=args.renderer, clips=args.clips)
    routes = sum(len(c.suite.routes) for c in protocol.cells)
    workers = min(args.workers or os.cpu_count() or 1, routes * len(models))
    print(f"benchmark: protocol '{protocol.name}' ({len(protocol.cells)} cells, {routes} routes, "
          f"{routes * protocol.seconds / 60:.0f} simulated minutes) x {len(models)} models "
          f"({', '.join(m.label for m in models)}), {workers} workers", file=sys.stderr)
    report = protocol_run.run_protocol(protocol, models, opts, out, workers, show_progress=sys.stderr.isatty(),
                          backend=args.backend)
    print(protocol_run.write_protocol(out, report).rstrip())
    print(f"\n{report['run']['wall_time_s']:.0f} s with {workers} workers; the table saved in {out}/protocol.md "
          f"(.csv, .json)")
    return 0
