"""The layering of docs/architecture.md, read from the code's own import statements (those inside functions too):
which package may import which, each world's modules apart from the other's and from the generic ones, nothing
below drivestudio/commands importing it, no import cycle between modules, and no import inside a function without
a comment saying why it is not at the top."""
import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "sim", "controller", "perception", "shm_bridge", "drivestudio", "assets")
WORLDS = ("highway", "sidewalk")
# a package may import these project packages (besides itself)
ALLOWED = {"core": set(), "assets": set(), "sim": {"core", "assets"}, "controller": {"core"},
           "perception": {"core"}, "shm_bridge": {"core"},
           "drivestudio": {"core", "assets", "sim", "controller", "perception", "shm_bridge"}}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}


def imports(path: Path, known: dict[str, Path]) -> set[str]:
    """The project modules a file imports (a `from package import module` counts as the module)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in known else node.module
                     for a in node.names]
        else:
            continue
        for name in names:
            while name and name not in known:
                name = name.rpartition(".")[0]
            if name and name.split(".")[0] in PACKAGES:
                out.add(name)
    return out


GRAPH = {m: imports(p, modules()) - {m} for m, p in modules().items()}


def world_of(module: str) -> str | None:
    parts = module.split(".")
    for w in WORLDS:
        if w in parts[1:]:
            return w
    return None


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_packages_import_only_the_layers_below(package):
    wrong = sorted(f"{m} imports {i}" for m, deps in GRAPH.items() if m.split(".")[0] == package
                   for i in deps if i.split(".")[0] not in ALLOWED[package] | {package})
    assert not wrong, wrong


def test_each_world_keeps_to_itself_and_generic_modules_name_no_world():
    """The verbs (drivestudio/commands/) are the top: a world's own verb (benchmark, autonomy, probe) names its
    world's package; everything else names only its own world, or the declarations of core/worlds/."""
    wrong = []
    for m, deps in GRAPH.items():
        if m.startswith("drivestudio.commands."):
            continue
        mine = world_of(m)
        for i in deps:
            theirs = world_of(i)
            if theirs is not None and theirs != mine and not i.startswith("core.worlds"):
                wrong.append(f"{m} imports {i}")
    # the declarations are the shared vocabulary: generic modules may read them; nothing else of a world
    assert not wrong, sorted(wrong)


def test_nothing_below_the_verbs_imports_them():
    top = ("drivestudio.commands", "drivestudio.cli", "drivestudio.__main__")
    wrong = sorted(f"{m} imports {i}" for m, deps in GRAPH.items() if not m.startswith(top)
                   for i in deps if i.startswith(top))
    assert not wrong, wrong


def test_there_is_no_import_cycle():
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        stack.append(m)
        for i in sorted(GRAPH.get(m, ())):
            if i.startswith(m + ".") or m.startswith(i + "."):
                continue   # a package and its own modules (its __init__ re-exporting them) are one unit
            if state.get(i) == 1:
                return stack[stack.index(i):] + [i]
            if i not in state and (cycle := visit(i)):
                return cycle
        stack.pop()
        state[m] = 2
        return None

    for m in sorted(GRAPH):
        if m not in state:
            cycle = visit(m)
            assert cycle is None, " -> ".join(cycle)


# files whose function-level imports are being reworked elsewhere (the benchmark's models, routes and runner); each
# import there is to get its comment with that work, and the file then leaves this set
PENDING: set[str] = set()   # files not yet held to the rule (none)
# a tool's marker alone is not a reason
PRAGMA = re.compile(r"#\s*(noqa(:\s*[A-Z]+[0-9]+(,\s*[A-Z]+[0-9]+)*)?|type:\s*ignore(\[[^]]*\])?|pragma:[^#]*)\s*$")


def uncommented_function_imports(path: Path) -> list[str]:
    """The imports inside functions with no comment on their lines or on a comment line just above them."""
    source = path.read_text()
    comments: dict[int, bool] = {}   # line -> the line is a comment only
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT and not PRAGMA.match(tok.string):
            comments[tok.start[0]] = tok.line.strip().startswith("#")
    found = set()
    for fn in ast.walk(ast.parse(source)):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for node in ast.walk(fn):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                lines = range(node.lineno, (node.end_lineno or node.lineno) + 1)
                if not any(n in comments for n in lines) and not comments.get(node.lineno - 1, False):
                    found.add(f"{path.relative_to(ROOT)}:{node.lineno}: {ast.get_source_segment(source, node)}")
    return sorted(found)


def test_imports_inside_functions_say_why():
    """Imports sit at the top of their files; one inside a function is a heavy dependency loaded only when needed
    (torch, matplotlib, pyarrow, aiohttp...: `drivestudio --help` and every verb pay for what their modules import
    at the top), and a comment on its line, or the line above it, says so."""
    wrong = [line for pkg in ("core", "sim", "perception", "controller", "shm_bridge", "drivestudio")
             for path in sorted((ROOT / pkg).rglob("*.py")) if str(path.relative_to(ROOT)) not in PENDING
             for line in uncommented_function_imports(path)]
    assert not wrong, "\n".join(wrong)
