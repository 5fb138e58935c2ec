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


def _prose(page: Path) -> str:
    """A page without its fenced code blocks (a `#` there is a comment, not a heading or a link)."""
    return re.sub(r"^```.*?^```", "", page.read_text(), flags=re.S | re.M)


def _slugs(page: Path) -> set[str]:
    """The anchors MkDocs gives a page's headings (the toc extension with mkdocs.yml's slugify)."""
    from pymdownx.slugs import slugify

    slug = slugify(case="lower")
    text = _prose(page)
    seen: set[str] = set()
    for heading in re.findall(r"^#{1,6} +(.+?) *#*$", text, flags=re.M):
        plain = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).replace("`", "").replace("*", "")
        name = base = slug(plain, "-")
        n = 0
        while name in seen:
            n += 1
            name = f"{base}_{n}"
        seen.add(name)
    return seen


def test_every_anchor_a_page_links_exists():
    """`mkdocs build --strict` refuses a link to a missing anchor; this says which, in a second."""
    broken = []
    for page in PAGES:
        path = DOCS / page
        text = _prose(path)
        for target, anchor in re.findall(r"\]\(([^)#\s]*)#([^)\s]+)\)", text):
            if target.startswith(("http:", "https:")):
                continue
            linked = (path.parent / target).resolve() if target else path
            if linked.suffix == ".md" and linked.exists() and anchor not in _slugs(linked):
                broken.append(f"docs/{page}: {target}#{anchor}")
    assert not broken, "links to missing anchors: " + "; ".join(broken)
