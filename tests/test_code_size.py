"""The size rule of the code: no module over 400 lines and no function over 80, in the package, the benchmarks and
the scripts. A long module or function hides more than one concept; the rule keeps each small enough to read."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("lerobot_pnp", "benchmarks", "scripts")
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 80


def _modules() -> list[Path]:
    return sorted(p for folder in FOLDERS for p in (ROOT / folder).rglob("*.py"))


def _functions(tree: ast.AST):
    """Every function and method, nested ones included, with its length from its first decorator to its end."""
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            start = min([node.lineno, *(d.lineno for d in node.decorator_list)])
            yield node, node.end_lineno - start + 1


def test_no_module_over_the_limit():
    long = {}
    for path in _modules():
        n = len(path.read_text().splitlines())
        if n > MAX_MODULE_LINES:
            long[str(path.relative_to(ROOT))] = n
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def test_no_function_over_the_limit():
    long = {}
    for path in _modules():
        for node, n in _functions(ast.parse(path.read_text(), str(path))):
            if n > MAX_FUNCTION_LINES:
                long[f"{path.relative_to(ROOT)}:{node.lineno} {node.name}"] = n
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines: {long}"


def test_the_checker_sees_a_long_function_and_a_nested_one():
    inner = "\n".join(f"        x{i} = {i}" for i in range(MAX_FUNCTION_LINES))
    tree = ast.parse(f"def outer():\n    @staticmethod\n    def inner():\n{inner}\n    return 1\n")
    sizes = {node.name: n for node, n in _functions(tree)}
    assert sizes == {"outer": MAX_FUNCTION_LINES + 4, "inner": MAX_FUNCTION_LINES + 2}
