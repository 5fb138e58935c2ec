"""The documentation reads in an evening: no hand-written page is over 400 lines (history belongs in the dated log,
docs/log/, one page per day or study), every page is in the site's navigation (mkdocs.yml), and the README stays a
front page. Generated pages (the command-line reference) and the bridge's wire protocol are exempt."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
MAX_LINES = 400
README_LINES = 150
EXEMPT = {"reference/cli.md", "shm-protocol.md"}
PAGES = sorted(p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md"))


@pytest.mark.parametrize("page", [p for p in PAGES if p not in EXEMPT])
def test_no_hand_written_page_is_over_400_lines(page):
    lines = len((DOCS / page).read_text().splitlines())
    assert lines <= MAX_LINES, f"docs/{page} has {lines} lines: move its history to docs/log/, or split it"


def test_every_page_is_in_the_sites_navigation():
    nav = set(re.findall(r"([\w./-]+\.md)", (REPO / "mkdocs.yml").read_text()))
    assert not set(PAGES) - nav


def test_the_readme_is_a_front_page():
    assert len((REPO / "README.md").read_text().splitlines()) <= README_LINES
