"""The generated command-line reference (docs/reference/cli.md) is what the parsers print: a verb's options, their
help or their defaults changed without the page fails here, naming the command that writes the page again."""
import argparse
import difflib

from drivestudio.cli import VERBS, build_parser
from drivestudio.commands.reference import COMMAND, PAGE, render


def test_the_cli_page_is_the_parsers_help():
    committed, now = PAGE.read_text(), render()
    if committed != now:
        diff = "\n".join(list(difflib.unified_diff(committed.splitlines(), now.splitlines(), "committed page",
                                                   "the parsers", n=1, lineterm=""))[:40])
        raise AssertionError(f"docs/reference/cli.md disagrees with the parsers; run `{COMMAND}` and commit the page."
                             f"\n{diff}")


def test_every_verb_has_its_section():
    verbs = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices
    text = render()
    assert set(VERBS) <= set(verbs)
    for verb in verbs:
        assert f"\n## {verb}\n" in text and f"usage: drivestudio {verb} " in text, verb
