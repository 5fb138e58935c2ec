"""Every ```python block of README.md and docs/**/*.md that a user would paste runs: the blocks of a page run in order
in one namespace (a later block may use what an earlier one made), in a scratch folder, in this process. A block
that is not meant to run as it stands says so on the line before its fence:

    <!-- fragment: WHY -->   it names things the reader brings (a dataset folder, a model, a loop); it must still
                             compile, and its imports of this project's packages must resolve
    <!-- slow: WHY -->       it runs, but for minutes or with several processes: only under `pytest -m slow`

The sh/bash blocks are not run; every `drivestudio VERB` named in them must be a verb the command has."""
from __future__ import annotations

import ast
import importlib
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from drivestudio.cli import build_parser

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
PACKAGES = ("core", "sim", "controller", "perception", "shm_bridge", "drivestudio")
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```[ \t]*$", re.S | re.M)
MARKER = re.compile(r"<!--\s*(fragment|slow)\b[^>]*-->\s*$")
VERB = re.compile(r"(?<![\w/.-])drivestudio\s+(?!-)([A-Za-z][\w-]*)")


@dataclass
class Block:
    page: Path
    line: int
    language: str
    code: str
    kind: str   # "run", "fragment" or "slow"

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(REPO)}:{self.line}"


def blocks(page: Path) -> list[Block]:
    text = page.read_text()
    out = []
    for m in FENCE.finditer(text):
        before = text[:m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        marker = MARKER.search(before)
        out.append(Block(page, text.count("\n", 0, m.start()) + 1, m.group(1), m.group(2),
                         marker.group(1) if marker else "run"))
    return out


def python_pages() -> list[Path]:
    return [p for p in PAGES if any(b.language == "python" for b in blocks(p))]


def project_imports(code: str) -> list[str]:
    """The modules of this project that the code imports (`from X import a, b` gives X.a and X.b as candidates)."""
    names: list[tuple[str, str | None]] = []
    for node in ast.walk(ast.parse(code)):
        if isinstance(node, ast.Import):
            names += [(a.name, None) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names += [(node.module, a.name) for a in node.names]
    return [f"{m}:{n}" if n else m for m, n in names if m.split(".")[0] in PACKAGES]


def check_import(spec: str) -> None:
    module, _, name = spec.partition(":")
    mod = importlib.import_module(module)
    if name and not hasattr(mod, name):
        importlib.import_module(f"{module}.{name}")   # a submodule, or ImportError naming what is missing


@pytest.fixture(autouse=True)
def scratch(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("DRIVESTUDIO_CACHE", str(tmp_path / "cache"))


def _run(page: Path, kinds: tuple[str, ...]) -> None:
    namespace: dict = {"__name__": "__docs__"}
    try:
        for block in blocks(page):
            if block.language != "python":
                continue
            code = compile(block.code, block.where, "exec")   # every block compiles, fragments too
            for spec in project_imports(block.code):
                try:
                    check_import(spec)
                except ImportError as e:
                    raise AssertionError(f"{block.where}: {e}") from None
            if block.kind in kinds:
                exec(code, namespace)
    finally:
        for value in list(namespace.values()):   # environments a page leaves open
            close = getattr(value, "close", None)
            if callable(close) and type(value).__module__.startswith(("gymnasium", "sim")):
                close()


@pytest.mark.parametrize("page", python_pages(), ids=lambda p: str(p.relative_to(REPO)))
def test_python_blocks_run(page):
    _run(page, ("run",))


@pytest.mark.slow
@pytest.mark.parametrize("page", [p for p in python_pages() if any(b.kind == "slow" for b in blocks(p))],
                         ids=lambda p: str(p.relative_to(REPO)))
def test_slow_python_blocks_run(page):
    _run(page, ("run", "slow"))


def test_every_marker_is_known_and_fragments_say_why():
    for page in PAGES:
        for line in page.read_text().splitlines():
            if line.strip().startswith("<!--") and re.match(r"<!--\s*(fragment|slow)", line.strip()):
                assert MARKER.search(line) and ":" in line, f"{page.name}: {line!r} (write <!-- fragment: why -->)"


def test_shell_blocks_name_only_verbs_that_exist():
    verbs = set(next(a for a in build_parser()._subparsers._group_actions   # type: ignore[union-attr]
                     if a.dest == "verb").choices)
    unknown = []
    for page in PAGES:
        for block in blocks(page):
            if block.language in ("sh", "bash", "console", "shell", ""):
                code = re.sub(r"(^|\s)#.*", "", block.code, flags=re.M)   # comments are prose
                unknown += [f"{block.where}: drivestudio {v}" for v in VERB.findall(code) if v not in verbs]
    assert not unknown, unknown
