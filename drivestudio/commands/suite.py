"""drivestudio suite --seed S --out SUITE.json: a benchmark suite of the highway nobody picked by hand, every route
drawn from one generator seed (drivestudio/worlds/highway/benchmark/draw.py, docs/benchmark.md)."""
from __future__ import annotations

import json

from core.files import atomic_write, check_output
from core.inputs import show_path
from drivestudio.commands.numbers import count, finite
from drivestudio.errors import UsageError
from drivestudio.worlds.highway.benchmark.draw import CARS, LANES, ROUTES, SECONDS, generator, suite_text
from drivestudio.worlds.highway.benchmark.suite import parse_suite


def register(sub) -> None:
    p = sub.add_parser("suite", help="draw a benchmark suite of random routes from a generator seed",
                       description="Draw a benchmark suite of random highway routes from a generator seed; the file "
                                   "records the generator, so anyone can draw it again (docs/benchmark.md).")
    p.add_argument("--seed", type=count(0, 2**32 - 1), required=True, help="the generator seed")
    p.add_argument("--routes", type=count(1, 200), default=ROUTES, help=f"routes (default {ROUTES})")
    p.add_argument("--lanes", type=count(1, 4), nargs=2, default=LANES, metavar=("LO", "HI"),
                   help=f"lane counts, from LO to HI (default {LANES[0]} {LANES[1]})")
    p.add_argument("--cars", type=count(0, 300), nargs=2, default=CARS, metavar=("LO", "HI"),
                   help=f"AI cars per route, from LO to HI (default {CARS[0]} {CARS[1]})")
    p.add_argument("--seconds", type=finite(1.0, 7200.0), default=SECONDS,
                   help=f"simulated seconds per route (default {SECONDS:g})")
    p.add_argument("--out", required=True, help="the suite file to write (.json); its name is the suite's")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.lanes[0] > args.lanes[1] or args.cars[0] > args.cars[1]:
        raise UsageError("--lanes and --cars take LO HI with LO <= HI")
    out = check_output(args.out, (".json",), "suite")
    try:
        text = suite_text(out.stem, generator(args.seed, args.routes, tuple(args.lanes),
                                                           tuple(args.cars), args.seconds))
    except ValueError as e:   # a track the generator cannot draw for these lanes
        raise UsageError(str(e)) from None
    parse_suite(json.loads(text), show_path(out), out.resolve().parent)   # a name or route it cannot drive
    atomic_write(out, text.encode())
    print(f"wrote {out}: {args.routes} routes drawn from seed {args.seed}")
    return 0
