"""No new import circle inside vebuild/.

Every ``import`` and ``from … import`` in every module of vebuild/ is read from its source (ast):
at module level, inside functions and under ``if TYPE_CHECKING:`` alike, since an import put inside
a function to dodge a loop still closes it. Modules that import each other, directly or round a
longer loop, form a circle (a strongly connected part of the import graph). Each circle found must
be one that is known and still open, listed below with why; a circle not listed fails, naming the
modules and the lines that tie it. A listed circle that is gone fails too, so that the list stays
true: take its line out.

What is not seen: a module loaded by name (``importlib.import_module``, as the command line loads
the parsers of its commands). An import of a module's own package (``vebuild.texture`` from
``vebuild.texture.gpu``) is left out: Python runs the package's ``__init__`` before any module in
it, so that tie is always there and marks no loop of the modules' own making.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "vebuild"

#: The circles still open, each as its modules (without the ``vebuild.`` in front) and why.
OPEN_CIRCLES: dict[frozenset[str], str] = {}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_names(node: ast.Import | ast.ImportFrom, module: str, is_package: bool) -> list[str]:
    """The dotted names that an import statement may load: for ``from A import b`` both ``A`` and
    ``A.b`` (b may be a module); relative imports resolved against ``module``."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    base = node.module or ""
    if node.level:
        package = module.split(".") if is_package else module.split(".")[:-1]
        package = package[: len(package) - (node.level - 1)]
        base = ".".join(package + ([node.module] if node.module else []))
    return [base] + [f"{base}.{alias.name}" for alias in node.names]


def import_graph() -> dict[str, dict[str, list[int]]]:
    """module → {module it imports → the lines of those imports}, within vebuild/."""
    files = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}
    graph: dict[str, dict[str, list[int]]] = {m: {} for m in files}
    for module, path in files.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            if not isinstance(node, ast.Import | ast.ImportFrom):
                continue
            for name in imported_names(node, module, path.name == "__init__.py"):
                while name and name not in files:  # a name inside a module: the module
                    name = name.rpartition(".")[0]
                if not name or name == module or module.startswith(name + "."):
                    continue
                graph[module].setdefault(name, []).append(node.lineno)
    return graph


def circles(graph: dict[str, dict[str, list[int]]]) -> list[frozenset[str]]:
    """The strongly connected parts of more than one module (Tarjan's algorithm, without recursion)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[frozenset[str]] = []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(graph[start]))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            v, targets = work[-1]
            for w in targets:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(graph[w])))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    part = set()
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        part.add(w)
                        if w == v:
                            break
                    if len(part) > 1:
                        found.append(frozenset(part))
    return found


def short(name: str) -> str:
    return name.removeprefix("vebuild.")


def described(circle: frozenset[str], graph: dict[str, dict[str, list[int]]]) -> str:
    ties = [f"    {short(a)} imports {short(b)} (line {', '.join(map(str, sorted(set(graph[a][b]))))})"
            for a in sorted(circle) for b in sorted(graph[a]) if b in circle]
    return " ↔ ".join(sorted(short(m) for m in circle)) + "\n" + "\n".join(ties)


def test_the_graph_sees_imports_inside_functions_and_a_circle_made_of_them() -> None:
    graph = import_graph()
    # At the top; inside a function (_cmd_calibrate); under TYPE_CHECKING (the Project).
    assert "vebuild.model.solver" in graph["vebuild.actions.solve"]
    assert "vebuild.analysis.project_check" in graph["vebuild.actions.calibrate_command"]
    assert "vebuild.project" in graph["vebuild.analysis.recorded"]
    # A loop closed by imports inside functions is found like any other.
    made_up = {"a": {"b": [3]}, "b": {"c": [9]}, "c": {"a": [40]}, "d": {"a": [1]}}
    assert circles(made_up) == [frozenset({"a", "b", "c"})]
    assert circles({"a": {"b": [1]}, "b": {}}) == []


def test_no_import_circle_but_the_known_open_ones() -> None:
    graph = import_graph()
    found = {frozenset(short(m) for m in c): c for c in circles(graph)}
    new = [described(full, graph) for c, full in found.items() if c not in OPEN_CIRCLES]
    assert not new, ("modules of vebuild/ that import each other in a loop; move what both need into a "
                     "module below them, or split a module by what it does:\n" + "\n".join(new))
    gone = [" ↔ ".join(sorted(c)) for c in OPEN_CIRCLES if c not in found]
    assert not gone, "these circles are broken now; take them out of OPEN_CIRCLES:\n" + "\n".join(gone)
