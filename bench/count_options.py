"""Print how many options each verb's --help shows (and the total), for the highway and the sidewalk."""
from __future__ import annotations

import argparse
import sys

from drivestudio import cli


def counts(world: str) -> dict[str, int]:
    cli.listed_world(["--world", world])
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    out = {}
    for verb, p in sub.choices.items():
        shown = [a for a in p._actions if a.option_strings and a.help != argparse.SUPPRESS
                 and "-h" not in a.option_strings]
        out[verb] = len(shown)
    return out


if __name__ == "__main__":
    for world in sys.argv[1:] or ["highway"]:
        c = counts(world)
        for verb, n in sorted(c.items(), key=lambda kv: -kv[1]):
            print(f"{world:8} {verb:10} {n}")
        print(f"{world:8} total      {sum(c.values())}")
