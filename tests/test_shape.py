"""The code keeps its shape: small modules, short functions.

How lines are counted: a module's lines are its physical lines; a function's are the non-blank lines of its
body and signature that are not comments and not its docstring (nested functions count in their parent too).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("online_slam", "benchmarks", "tests")
MODULE_LINES = 600
FUNCTION_LINES = 80


def _sources() -> list[Path]:
    return sorted(p for folder in FOLDERS for p in (ROOT / folder).rglob("*.py"))


def code_lines(lines: list[str], node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines of code of a function: not blank, not a comment, not its docstring."""
    first = node.body[0]
    docstring = range(0)
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        docstring = range(first.lineno, (first.end_lineno or first.lineno) + 1)
    start = min([node.lineno, *(d.lineno for d in node.decorator_list)])
    numbers = range(start, (node.end_lineno or node.lineno) + 1)
    return sum(1 for n in numbers if n not in docstring and lines[n - 1].strip()[:1] not in ("", "#"))


def test_counting_rules() -> None:
    source = 'def f(x):\n    """Doc.\n\n    More.\n    """\n    # a comment\n\n    y = x\n    return y\n'
    node = ast.parse(source).body[0]
    assert isinstance(node, ast.FunctionDef)
    assert code_lines(source.splitlines(), node) == 3


def test_modules_and_functions_are_small() -> None:
    found = []
    for path in _sources():
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        name = path.relative_to(ROOT)
        if len(lines) > MODULE_LINES:
            found.append(f"{name}: {len(lines)} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and code_lines(lines, node) > FUNCTION_LINES:
                found.append(f"{name}: {node.name} has {code_lines(lines, node)} lines of code")
    assert not found, "\n".join(found)
