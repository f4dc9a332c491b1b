"""The import graph of ``usdmotion``: one-way, no cycles, no BVH details outside ``io/``.

Built with :mod:`ast` from the source (every ``import`` statement, at module top or inside
functions), so imports deferred into functions cannot hide a cycle.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "usdmotion"
#: What ``ops`` may take from ``io``: the format-neutral entry points, and the atomic
#: writer for operations that truly write files (reports, clips).
OPS_IO_NAMES = {"read_motion", "write_motion", "BVH_EXTENSIONS", "USD_EXTENSIONS"}
OPS_IO_MODULES = {"usdmotion.io.atomic"}


def module_names() -> dict[str, Path]:
    """Dotted module name → source file, for every module of the package."""
    names = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return names


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> list[tuple[str, tuple[str, ...], int]]:
    """``(imported usdmotion module, names taken from it, line)`` for every import in ``path``."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, (), node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else []))
            submodules = [a.name for a in node.names if f"{base}.{a.name}" in modules]
            found += [(f"{base}.{sub}", (), node.lineno) for sub in submodules]
            rest = tuple(a.name for a in node.names if a.name not in submodules)
            if rest or not submodules:
                found.append((base, rest, node.lineno))
    return [(m, names, line) for m, names, line in found if m in modules]


@pytest.fixture(scope="module")
def graph() -> dict[str, list[tuple[str, tuple[str, ...], int]]]:
    modules = module_names()
    assert "usdmotion.motion" in modules and "usdmotion.ops.retarget.solve" in modules
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module, or a module importing itself (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
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
            if len(component) > 1 or v in edges.get(v, ()):
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_cycle_finder_finds_a_planted_cycle():
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"e"}}
    assert cycles(edges) == [["a", "b", "c"], ["e"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles(graph):
    edges = {name: {m for m, _, _ in imports} for name, imports in graph.items()}
    assert cycles(edges) == []


def test_import_graph_sees_function_level_imports(graph):
    # solve imports JAX inside functions, and the CLI imports its library modules there.
    cli = {m for m, _, _ in graph["usdmotion.cli.retarget"]}
    assert "usdmotion.ops.retarget.solve" in cli or "usdmotion.ops.retarget.files" in cli


def test_ops_and_render_do_not_import_bvh(graph):
    leaks = [f"{name}:{line} imports {m}" for name, imports in graph.items()
             if name.startswith(("usdmotion.ops", "usdmotion.render"))
             for m, _, line in imports if m.startswith(("usdmotion.io.bvh", "usdmotion.io.usd"))]
    assert leaks == []


def test_ops_use_io_only_through_read_write_motion(graph):
    leaks = []
    for name, imports in graph.items():
        if not name.startswith("usdmotion.ops"):
            continue
        for m, names, line in imports:
            if m == "usdmotion.io" and set(names) <= OPS_IO_NAMES and names:
                continue
            if m.startswith("usdmotion.io") and m not in OPS_IO_MODULES:
                leaks.append(f"{name}:{line} imports {m} {names}")
    assert leaks == []


def test_no_module_over_500_lines():
    long = {str(path.relative_to(PACKAGE.parent)): n for path in PACKAGE.rglob("*.py")
            if (n := len(path.read_text(encoding="utf-8").splitlines())) > 500}
    assert long == {}
