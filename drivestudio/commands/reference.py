"""The command-line reference page, docs/reference/cli.md, written from the parsers themselves: every verb's
`--help` as the command prints it, once per world where a world lists other options. A test regenerates it in
memory and fails when the committed page and the parsers disagree.

    python -m drivestudio.commands.reference          # rewrites docs/reference/cli.md
    python -m drivestudio.commands.reference --check  # exit status 1 when the page is out of date
"""
from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

PAGE = Path(__file__).resolve().parents[2] / "docs" / "reference" / "cli.md"
COMMAND = "python -m drivestudio.commands.reference"
WIDTH = 100   # the terminal width the help is formatted for, so that the page does not depend on the terminal


@contextmanager
def _columns(width: int) -> Iterator[None]:
    """argparse wraps its help to the terminal's width ($COLUMNS): a fixed width for the page."""
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(width)
    try:
        yield
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old


def _helps(world: str) -> tuple[str, dict[str, tuple[str, str]]]:
    """The top-level help and, per verb in the parser's order, (one-line summary, full --help) as
    `drivestudio --world WORLD VERB --help` prints them."""
    from drivestudio.cli import build_parser  # lazy: every verb and world, only when the page is written
    from drivestudio.commands.common import HELP_WORLD  # lazy: as above
    listed = HELP_WORLD[0]
    HELP_WORLD[0] = world
    try:
        parser = build_parser()
    finally:
        HELP_WORLD[0] = listed
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    summaries = {a.dest: a.help or "" for a in sub._choices_actions}
    return parser.format_help(), {verb: (summaries.get(verb, ""), p.format_help()) for verb, p in sub.choices.items()}


def _block(text: str) -> str:
    return "```text\n" + text.rstrip() + "\n```\n"


def render() -> str:
    """The page's text."""
    from drivestudio import worlds  # lazy: as above
    names = worlds.names()
    with _columns(WIDTH):
        top, first = _helps(names[0])
        others = {w: _helps(w)[1] for w in names[1:]}
    out = ["# Command-line reference", "",
           f"<!-- generated from the parsers by `{COMMAND}`: do not edit by hand -->", "",
           "Every verb of `drivestudio` with its options, their help and their defaults, exactly as `--help` prints "
           "them. Where a verb serves several worlds and a world lists other options, each world's help is given "
           f"(`drivestudio VERB --world {names[-1]} --help` prints the {names[-1]} world's). The world's settings "
           "that have no option of their own are listed with their defaults under `--set NAME=VALUE` "
           "([configuration](../configuration.md)). The page is written from the code by "
           f"`{COMMAND}`, and a test fails when it and the parsers disagree.", "",
           "Verbs: " + " · ".join(f"[{v}](#{v})" for v in first), "",
           "## drivestudio", "", _block(top)]
    for verb, (summary, text) in first.items():
        out += [f"## {verb}", "", summary[:1].upper() + summary[1:] + ".", ""]
        variants = [(names[0], text)] + [(w, others[w][verb][1]) for w in names[1:] if verb in others[w]]
        if all(t == text for _, t in variants):
            out.append(_block(text))
            continue
        for world, t in variants:
            out += [f"### {verb} --world {world}", "", _block(t)]
    return "\n".join(out).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog=COMMAND, description="write docs/reference/cli.md from the parsers")
    p.add_argument("--check", action="store_true", help="only compare; exit status 1 when the page is out of date")
    args = p.parse_args(argv)
    text = render()
    if args.check:
        if not PAGE.is_file() or PAGE.read_text() != text:
            print(f"{PAGE}: out of date; run `{COMMAND}`", file=sys.stderr)
            return 1
        return 0
    PAGE.parent.mkdir(parents=True, exist_ok=True)
    PAGE.write_text(text)
    print(f"wrote {PAGE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
