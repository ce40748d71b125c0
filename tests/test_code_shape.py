"""The stack's code stays small in its parts: no function past 60 lines, no constructor past 6 parameters.

Read with `ast` from the source of every module under replay/stack/, so a
new module is checked without being listed here.
"""

from __future__ import annotations

import ast
from pathlib import Path

STACK = Path(__file__).resolve().parents[1] / "replay" / "stack"
MAX_LINES = 60
MAX_INIT_PARAMETERS = 6      # self excluded: group the rest into a frozen dataclass (see replay.stack.runner_options)

# Known exceptions, by "module path:Class.__init__": none left (the DR error model and the leader-exclusion
# filters take their tuning as one frozen dataclass each)
INIT_EXCEPTIONS: dict[str, str] = {}


def _functions() -> list[tuple[str, ast.FunctionDef | ast.AsyncFunctionDef]]:
    """Every function and method under replay/stack/, named "path:Class.name" (path relative to the stack)."""
    out = []
    for path in sorted(STACK.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        rel = path.relative_to(STACK).as_posix()
        for parent in ast.walk(tree):
            for node in ast.iter_child_nodes(parent):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    owner = f"{parent.name}." if isinstance(parent, ast.ClassDef) else ""
                    out.append((f"{rel}:{owner}{node.name}", node))
    return out


def _parameters(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Parameters of a method, self excluded (*args and **kwargs count one each)."""
    a = node.args
    return len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + (a.vararg is not None) + (a.kwarg is not None) - 1


def test_the_checker_reads_the_stack() -> None:
    """The walk finds the runner's methods and counts lines and parameters as the source shows them."""
    found = dict(_functions())
    assert "runner.py:CooperativeRunner.range_epoch" in found and "runner.py:CooperativeRunner.__init__" in found
    init = found["runner.py:CooperativeRunner.__init__"]
    assert _parameters(init) == 6    # config, follower, leaders, start, options, parts
    source = ast.parse("class A:\n    def __init__(self, a, b, *c, d=1, **e):\n        pass\n").body[0]
    assert isinstance(source, ast.ClassDef) and isinstance(source.body[0], ast.FunctionDef)
    assert _parameters(source.body[0]) == 5


def test_no_function_runs_past_60_lines() -> None:
    long = {name: node.end_lineno - node.lineno + 1 for name, node in _functions()
            if node.end_lineno is not None and node.end_lineno - node.lineno + 1 > MAX_LINES}
    assert long == {}


def test_no_constructor_takes_more_than_6_parameters() -> None:
    wide = {name: _parameters(node) for name, node in _functions()
            if node.name == "__init__" and _parameters(node) > MAX_INIT_PARAMETERS and name not in INIT_EXCEPTIONS}
    assert wide == {}


def test_every_exception_is_still_needed() -> None:
    """An exception whose constructor was slimmed (or removed) is dropped from the list."""
    inits = {name: _parameters(node) for name, node in _functions() if node.name == "__init__"}
    assert {name: inits.get(name, 0) > MAX_INIT_PARAMETERS for name in INIT_EXCEPTIONS} == dict.fromkeys(
        INIT_EXCEPTIONS, True)
