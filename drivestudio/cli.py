"""`drivestudio VERB ...`: the user's jobs as verbs of one command."""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from drivestudio.errors import input_errors, runtime_errors

VERBS = ("probe", "render", "generate", "stats", "train", "evaluate", "overlay", "serve", "drive", "benchmark",
         "autonomy", "study", "export", "demo")


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, not a usage dump
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="drivestudio", description="Headless driving world with exact DeepDriving "
                     "affordances, the models that read them and the loop that drives from them.")
    sub = parser.add_subparsers(dest="verb", metavar="VERB", parser_class=_Parser)
    sub.required = True
    for verb in VERBS:
        importlib.import_module(f"drivestudio.commands.{verb}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        from drivestudio.worlds import load_external
        load_external()
    except input_errors() as e:
        print(f"drivestudio: error: {e}", file=sys.stderr)
        return 2
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except input_errors() as e:
        print(f"drivestudio {args.verb}: error: {e}", file=sys.stderr)
        return 2
    except runtime_errors() as e:
        print(f"drivestudio {args.verb}: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"drivestudio {args.verb}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader of our output went away (e.g. `| head`): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
