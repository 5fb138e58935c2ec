"""The layering of docs/architecture.md, read from the code's own import statements (those inside functions too):
which package may import which, each world's modules apart from the other's and from the generic ones, nothing
below drivestudio/commands importing it, and no import cycle between modules."""
import ast
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
