"""drivestudio ensemble --out E.pt A.pt B.pt ...: one checkpoint of several trained regressors of a world
(drivestudio/ensemble.py): each reads the same frames, the closest gap any of them reads is believed, every other
output is their mean."""
from __future__ import annotations

from core.files import check_output
from drivestudio.errors import UsageError


def register(sub) -> None:
    p = sub.add_parser("ensemble", help="make one checkpoint of several trained regressors of a world",
                       description="Make one checkpoint of several trained regressors of a world: the closest gap "
                                   "any of them reads, the mean of every other output, each over the members that "
                                   "estimate it (docs/explanation/learned-driving.md). The members must read the "
                                   "same input.")
    p.add_argument("checkpoints", nargs="+", help="the members' checkpoint files (two or more)")
    p.add_argument("--out", required=True, help="the ensemble's checkpoint file to write (.pt)")
    p.add_argument("--gaps", default="min", help="the gaps: the closest reading (min, the default) or the mean")
    p.set_defaults(func=run)


def run(args) -> int:
    from drivestudio.ensemble import make  # lazy: torch, only when an ensemble is made
    from perception.checkpoint import save_checkpoint  # lazy: torch
    from perception.ensemble import COMBINE  # lazy: torch
    from perception.models import describe  # lazy: torch
    if args.gaps not in COMBINE:
        raise UsageError(f"--gaps must be one of {', '.join(COMBINE)}, got {args.gaps!r}")
    out = check_output(args.out, (".pt",), "checkpoint")
    payload = make(args.checkpoints, args.gaps)
    save_checkpoint(out, payload)
    print(f"wrote {out}: {describe(payload['spec'])}")
    return 0
