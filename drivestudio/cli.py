"""`drivestudio VERB ...`: the user's jobs as verbs of one command."""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from core.signals import Terminated
from drivestudio.commands.parsing import Parser
from drivestudio.errors import input_errors, runtime_errors

# the verbs that serve every world (--world where it matters); a world's own verbs are its Plugin's `verbs`
VERBS = ("render", "generate", "stats", "train", "evaluate", "overlay", "ensemble", "export", "serve", "drive",
         "studio", "demo")


def build_parser() -> argparse.ArgumentParser:
    from drivestudio import worlds  # lazy: `import drivestudio.cli` loads no world
    plugins = worlds.all_plugins()
    own = "\n".join(f"  {p.name + ':':<10}{', '.join(p.verbs)}" for p in plugins if p.verbs)
    parser = Parser(prog="drivestudio", formatter_class=argparse.RawDescriptionHelpFormatter,
                    description="Headless driving world with exact DeepDriving affordances, the models that read "
                                "them and the loop that drives from them.",
                    epilog=f"verbs of every world: {', '.join(VERBS)}\nverbs of one world:\n{own}")
    sub = parser.add_subparsers(dest="verb", metavar="VERB", parser_class=Parser)
    sub.required = True
    for verb in VERBS:
        importlib.import_module(f"drivestudio.commands.{verb}").register(sub)
    for plugin in plugins:
        for verb in plugin.verbs:
            importlib.import_module(f"drivestudio.commands.{verb}").register(sub)
            sub.choices[verb].world = plugin.name   # type: ignore[attr-defined]
            action = next(a for a in sub._choices_actions if a.dest == verb)
            action.help = f"({plugin.name}) {action.help}"
    parser.verbs = sub.choices   # type: ignore[attr-defined]
    return parser


def parse(argv: list[str] | None) -> argparse.Namespace:
    """The command line; an option its verb does not know is refused by that verb's parser (its name in the line)."""
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:
        parser.verbs[args.verb].error(f"unrecognized arguments: {' '.join(extra)}")   # type: ignore[attr-defined]
    return args


def listed_world(argv: list[str]) -> None:
    """The world whose options --help lists: the command line's --world, if it names one."""
    from drivestudio.commands.common import HELP_WORLD  # lazy: as the verbs, once a command line is read
    HELP_WORLD[0] = "highway"
    for i, a in enumerate(argv):
        if a == "--world" and i + 1 < len(argv):
            HELP_WORLD[0] = argv[i + 1]
        elif a.startswith("--world="):
            HELP_WORLD[0] = a.split("=", 1)[1]


def main(argv: list[str] | None = None) -> int:
    try:
        from drivestudio.worlds import load_external  # lazy: `import drivestudio.cli` loads no world
        load_external()
    except input_errors() as e:
        print(f"drivestudio: error: {e}", file=sys.stderr)
        return 2
    listed_world(sys.argv[1:] if argv is None else argv)
    args = parse(argv)
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
