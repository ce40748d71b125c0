"""The package layers, read from the source with `ast`: who may import whom.

`formats` <- `recorders` <- `replay`; inside `replay`, the folders form no loop, and neither
`replay/engine` nor `replay/review` imports `replay/run` (the engine and the review sit below
the run pipeline). Every static import counts, function-local ones included.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("formats", "recorders", "replay")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _resolve(module: str, is_package: bool, level: int, target: str | None) -> str:
    """The absolute name a relative `from ... import` names."""
    if level == 0:
        return target or ""
    base = module.split(".")
    if not is_package:
        base = base[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join(base + ([target] if target else []))


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def imports_of(path: Path) -> Iterator[tuple[int, str, bool]]:
    """(line, absolute module name, for the type checker only) of every static import in one file.

    Imports at any depth count (function-local ones too); those under `if TYPE_CHECKING:` are
    flagged, since they name types without importing anything when the program runs.
    """
    module = _module_name(path)
    is_package = path.name == "__init__.py"

    def walk(node: ast.AST, type_only: bool) -> Iterator[tuple[int, str, bool]]:
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name, type_only
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(module, is_package, node.level, node.module)
            # the imported name may be a module (`from replay import events`); as a prefix test
            # on module names, `replay.run.config.RunConfig` still lies under `replay.run`
            for alias in node.names:
                yield node.lineno, f"{base}.{alias.name}", type_only
        elif isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.body:
                yield from walk(child, True)
            for child in node.orelse:
                yield from walk(child, type_only)
        else:
            for child in ast.iter_child_nodes(node):
                yield from walk(child, type_only)

    yield from walk(ast.parse(path.read_text(), filename=str(path)), False)


def all_imports() -> list[tuple[str, int, str, str, bool]]:
    """(file, line, importing module, imported module, type-only) of our three packages' imports of each other."""
    out = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            mod = _module_name(path)
            rel = str(path.relative_to(ROOT))
            for line, target, type_only in imports_of(path):
                if target.split(".")[0] in PACKAGES:
                    out.append((rel, line, mod, target, type_only))
    return out


def _under(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def _violations(source: str, forbidden: tuple[str, ...]) -> list[str]:
    return [f"{path}:{line}: {target}" for path, line, mod, target, _ in all_imports()
            if _under(mod, source) and any(_under(target, f) for f in forbidden)]


@pytest.mark.parametrize(("source", "forbidden"), [
    ("formats", ("recorders", "replay")),
    ("recorders", ("replay",)),
    ("replay.engine", ("replay.run",)),
    ("replay.review", ("replay.run",)),
    ("replay.stack", ("replay.engine", "replay.run", "replay.review", "replay.views", "replay.commands")),
])
def test_layer_imports_nothing_above_it(source: str, forbidden: tuple[str, ...]) -> None:
    assert _violations(source, forbidden) == []


def _part(module: str) -> str | None:
    """The top-level part of `replay` a module belongs to: a folder or a lone module."""
    parts = module.split(".")
    return parts[1] if parts[0] == "replay" and len(parts) > 1 else None


def folder_graph() -> dict[str, dict[str, list[str]]]:
    """part -> imported part -> the import sites, for run-time imports between different parts of replay.

    `replay/events.py` names two stack types for the type checker only while the stack builds its
    events at run time; a type-only name is no import loop, so those imports are left out here (the
    layer rules above still count them).
    """
    graph: dict[str, dict[str, list[str]]] = {}
    for path, line, mod, target, type_only in all_imports():
        a, b = _part(mod), _part(target)
        if a is not None and b is not None and a != b and not type_only:
            graph.setdefault(a, {}).setdefault(b, []).append(f"{path}:{line}")
    return graph


def find_cycle(graph: dict[str, dict[str, list[str]]]) -> list[str]:
    """One cycle of the graph as its nodes (first repeated at the end), or [] if it is acyclic."""
    state: dict[str, int] = {}   # 1 on the current path, 2 finished
    path: list[str] = []

    def visit(node: str) -> list[str]:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, {})):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        path.pop()
        state[node] = 2
        return []

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return []


def test_find_cycle_finds_a_loop_and_only_a_loop() -> None:
    assert find_cycle({"a": {"b": []}, "b": {"c": []}, "c": {"a": []}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b": [], "c": []}, "b": {"c": []}}) == []


def test_resolve_relative_imports() -> None:
    assert _resolve("formats.novatel.scan", False, 2, "lines") == "formats.lines"
    assert _resolve("formats.novatel", True, 1, "logs") == "formats.novatel.logs"
    assert _resolve("formats.nortek", False, 1, "lines") == "formats.lines"


def test_no_loop_between_the_folders_of_replay() -> None:
    graph = folder_graph()
    assert "engine" in graph and "stack" in graph["engine"]   # the graph is really read
    cycle = find_cycle(graph)
    sites = [f"{a} -> {b}: {', '.join(sorted(set(graph[a][b])))}" for a, b in zip(cycle, cycle[1:], strict=False)]
    assert cycle == [], "import loop:\n" + "\n".join(sites)
