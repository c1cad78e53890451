"""Meta-tests of the layout (docs/architecture.md): no import cycles among the core's
modules, and the rooms import only what their job needs.

The import graph is read with `ast` from coadapt_core's source: one edge per `import` /
`from ... import` of a core module (`from pkg import name` is an edge to `pkg.name` when
that is a module, else to `pkg`; an import under `if TYPE_CHECKING:` is no edge). Edges are
told apart by where the import stands: at module level (run when the module is imported)
or inside a function (run when the function is called). A cycle of module-level edges can
break an import outright; a cycle that needs a function-level edge imports fine but still
ties two rooms into one, so both kinds are checked. Importing a module also runs its
packages' `__init__`; those implicit edges are not counted.

KNOWN_CYCLES lists the cycles (through function-level imports) that remain, each with why;
it may only shrink."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CORE = "coadapt_core"

#: strongly connected components of the full import graph still there, and why (may only shrink)
KNOWN_CYCLES: dict[frozenset[str], str] = {}


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def import_edges(path: Path, name: str, modules: set[str]) -> list[tuple[str, bool]]:
    """(imported core module, imported inside a function) for every import in `path`."""
    tree = ast.parse(path.read_text())
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    out: list[tuple[str, bool]] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(
                child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda
            )
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue
            if isinstance(child, ast.Import):
                out.extend((a.name, inner) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    parent = package[: len(package) - (child.level - 1)]
                    base = ".".join(parent + ([base] if base else []))
                for alias in child.names:
                    full = f"{base}.{alias.name}"
                    out.append((full if full in modules else base, inner))
            visit(child, inner)

    visit(tree, False)
    return [(target, inner) for target, inner in out if target in modules and target != name]


def import_graph(root: Path = ROOT, package: str = CORE) -> dict[str, list[tuple[str, bool]]]:
    files = {module_name(p, root): p for p in sorted((root / package).rglob("*.py"))}
    modules = set(files)
    return {name: import_edges(path, name, modules) for name, path in files.items()}


def cycles(
    graph: dict[str, list[tuple[str, bool]]], *, function_level: bool
) -> list[frozenset[str]]:
    """Strongly connected components of more than one module (Tarjan), over module-level
    edges only, or over all edges (`function_level`)."""
    adjacency = {
        m: [t for t, inner in edges if function_level or not inner] for m, edges in graph.items()
    }
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[frozenset[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in adjacency[v]:
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(frozenset(component))

    for v in adjacency:
        if v not in index:
            connect(v)
    return found


def imports_of(graph: dict[str, list[tuple[str, bool]]], room: str) -> dict[str, set[str]]:
    """Module of the room -> the core modules it imports (at any level)."""
    return {
        m: {t for t, _ in edges}
        for m, edges in graph.items()
        if m == room or m.startswith(room + ".")
    }


def reachable(graph: dict[str, list[tuple[str, bool]]], start: str) -> set[str]:
    """Core modules run, directly or not, when `start` is imported: its module-level imports
    and, for each module imported, its packages' `__init__`."""
    seen, todo = set(), [start]
    while todo:
        module = todo.pop()
        parents = [".".join(module.split(".")[:i]) for i in range(1, module.count(".") + 1)]
        for target in [t for t, inner in graph[module] if not inner] + [
            p for p in parents if p in graph
        ]:
            if target not in seen:
                seen.add(target)
                todo.append(target)
    return seen


def _in(module: str, rooms: tuple[str, ...]) -> bool:
    return any(module == r or module.startswith(r + ".") for r in rooms)


GRAPH = import_graph()


def test_no_import_cycle_at_module_level():
    assert cycles(GRAPH, function_level=False) == []


def test_no_import_cycle_through_function_level_imports_but_the_known_ones():
    found = set(cycles(GRAPH, function_level=True))
    new = [sorted(c) for c in found - set(KNOWN_CYCLES)]
    assert not new, f"import cycles (counting imports inside functions): {new}"
    gone = [sorted(c) for c in set(KNOWN_CYCLES) - found]
    assert not gone, f"these cycles are gone: remove them from KNOWN_CYCLES: {gone}"


def test_results_room_imports_neither_learning_physics_nor_experiments():
    """The store, recorders and export work without the learner or a simulator: no import
    of them at any level, and none reached through module-level imports."""
    forbidden = (
        f"{CORE}.learning",
        f"{CORE}.physics",
        f"{CORE}.experiments",
        f"{CORE}.analysis",
        f"{CORE}.task",
        f"{CORE}.viz",
        f"{CORE}.cli",
    )
    direct = {
        m: sorted(t for t in targets if _in(t, forbidden))
        for m, targets in imports_of(GRAPH, f"{CORE}.results").items()
    }
    assert len(direct) >= 4  # the room exists and was read
    assert {m: t for m, t in direct.items() if t} == {}
    assert {m: sorted(t for t in reachable(GRAPH, m) if _in(t, forbidden)) for m in direct} == {
        m: [] for m in direct
    }


def test_analysis_room_reads_only():
    """Reports run no simulation and write no row: no import of the learner, physics, the
    task, the experiments or the CLI, and no call of a store method that writes."""
    forbidden = (
        f"{CORE}.learning",
        f"{CORE}.physics",
        f"{CORE}.task",
        f"{CORE}.experiments",
        f"{CORE}.cli",
    )
    modules = imports_of(GRAPH, f"{CORE}.analysis")
    assert len(modules) >= 3
    assert {
        m: sorted(t for t in ts if _in(t, forbidden))
        for m, ts in modules.items()
        if any(_in(t, forbidden) for t in ts)
    } == {}
    writes = {
        "record_evaluations",
        "record_evaluation",
        "record_training",
        "record_checkpoint",
        "create_run",
        "finish_run",
        "set_status",
        "save_grid",
        "set_cell",
        "real_fitness",
        "surrogate_fitness",
    }
    calls = []
    for path in (ROOT / CORE / "analysis").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr in writes
            ):
                calls.append(f"{path.name}:{node.lineno} .{node.func.attr}()")
    assert calls == []


def test_the_checks_find_a_planted_cycle_and_a_forbidden_import(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "results").mkdir(parents=True)
    (pkg / "learning").mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "results" / "__init__.py").write_text("")
    (pkg / "learning" / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from pkg import b\n")
    (pkg / "b.py").write_text("def f():\n    from pkg.a import x\n")
    (pkg / "c.py").write_text("import pkg.d\n")
    (pkg / "d.py").write_text("from . import c\n")
    (pkg / "results" / "store.py").write_text("from ..learning import trainer\n")
    (pkg / "learning" / "trainer.py").write_text("")
    graph = import_graph(tmp_path, "pkg")
    assert cycles(graph, function_level=False) == [frozenset({"pkg.c", "pkg.d"})]
    assert set(cycles(graph, function_level=True)) == {
        frozenset({"pkg.a", "pkg.b"}),
        frozenset({"pkg.c", "pkg.d"}),
    }
    assert imports_of(graph, "pkg.results") == {
        "pkg.results": set(),
        "pkg.results.store": {"pkg.learning.trainer"},
    }
