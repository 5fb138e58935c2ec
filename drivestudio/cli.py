"""`drivestudio VERB ...`: the user's jobs as verbs of one command."""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from core.signals import Terminated
from drivestudio.errors import input_errors, runtime_errors
from drivestudio.parsing import Parser

VERBS = ("probe", "render", "generate", "stats", "train", "evaluate", "overlay", "serve", "drive", "benchmark",
         "aggregate", "recipe", "autonomy", "study", "export", "demo", "studio")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="drivestudio", description="Headless driving world with exact DeepDriving "
                     "affordances, the models that read them and the loop that drives from them.")
    sub = parser.add_subparsers(dest="verb", metavar="VERB", parser_class=Parser)
    sub.required = True
    for verb in VERBS:
        importlib.import_module(f"drivestudio.commands.{verb}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        from drivestudio.worlds import load_external  # lazy: `import drivestudio.cli` loads no world
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
    except Terminated as e:   # SIGTERM or SIGHUP inside exit_on_sigterm(): what was saved has been said
        print(f"drivestudio {args.verb}: {e}", file=sys.stderr)
        return 128 + e.signum
    except BrokenPipeError:  # the reader of our output went away (e.g. `| head`): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
