"""No import circles among the ankle_rt modules (issue 13), counting imports deferred into functions
(they only hide a circle) but not those under TYPE_CHECKING (never run)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "ankle_rt"


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, modules: set[str]) -> set[str]:
    """Project modules ``path`` imports anywhere, at module level or deferred inside a function (a
    deferred import only hides a circle), except under ``if TYPE_CHECKING:`` (never run).
    ``from pkg import mod`` counts as mod."""
    tree = ast.parse(path.read_text(), str(path))
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    skipped = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
               for stmt in node.body for n in ast.walk(stmt)}
    found: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[:len(parts) - node.level + 1] + ([base] if base else []))
            for alias in node.names:
                full = f"{base}.{alias.name}"
                found.add(full if full in modules else base)
    # importing a.b.c first runs the package a.b's __init__ (unless it is one of the importer's own
    # packages, which are initialised before the importer runs)
    own = {name.rsplit(".", k)[0] for k in range(1, name.count(".") + 1)}
    found |= {m.rsplit(".", k)[0] for m in found for k in range(1, m.count(".") + 1)} - own
    return {m for m in found if m in modules and m != name}


def import_graph() -> dict[str, set[str]]:
    files = sorted(PACKAGE.rglob("*.py"))
    modules = {module_name(f) for f in files}
    return {module_name(f): imports(f, modules) for f in files}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle per strongly connected component with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in graph:
        if v not in index:
            strong(v)
    return found


def test_the_graph_sees_the_imports_it_should():
    graph = import_graph()
    assert "ankle_rt.config_schema" in graph["ankle_rt.config"]
    assert "ankle_rt.schema" in graph["ankle_rt.references"]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    # a submodule import runs its package's __init__ (how config -> ... -> ankle_rt.control closed a
    # circle at run time); a module's own packages do not count
    assert "ankle_rt.control" in graph["ankle_rt.config_schema"] or \
        not any(m.startswith("ankle_rt.control.") for m in graph["ankle_rt.config_schema"])
    assert "ankle_rt.control" not in graph["ankle_rt.control.pd"]


def test_no_import_circles_in_ankle_rt():
    assert cycles(import_graph()) == []


def test_ankle_rt_reaches_backends_and_simulators_only_by_name():
    """The core knows hardware/ and sim_backend/ by registered names (ankle_rt.backend), never by an
    import statement, deferred or not (the batch simulator of the sweeps came in directly once)."""
    direct = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            direct += [f"{path.relative_to(PACKAGE.parent)}:{node.lineno} {n}" for n in names
                       if n.split(".")[0] in ("hardware", "sim_backend")]
    assert direct == []
