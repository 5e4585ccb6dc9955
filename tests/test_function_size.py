"""Every function in src/ is under 80 lines, not counting multi-line data literals.

A function's size is the lines from its ``def`` to its end, docstring and comments included,
minus the lines of dict / list / tuple / set / string literals that span several lines (tables
of numbers, option lists, help texts): data, not logic.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LIMIT = 80
LITERALS = (ast.Dict, ast.List, ast.Tuple, ast.Set, ast.Constant, ast.JoinedStr)


def function_size(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    lines = set(range(fn.lineno, fn.end_lineno + 1))
    first = fn.body[0]
    docstring = (
        first.value
        if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
        else None
    )
    for node in ast.walk(fn):
        if node is fn or node is docstring or not isinstance(node, LITERALS):
            continue
        if node.end_lineno > node.lineno:
            lines -= set(range(node.lineno, node.end_lineno + 1))
    return len(lines)


def sizes(source: str) -> list[tuple[int, str]]:
    tree = ast.parse(source)
    return [
        (function_size(node), f"{node.name}:{node.lineno}")
        for node in ast.walk(tree)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
    ]


def test_the_measure_counts_logic_not_data():
    body = "\n".join(f"    x{i} = {i}" for i in range(10))
    table = "    T = [\n" + "".join(f"        {i},\n" for i in range(50)) + "    ]"
    source = f'def f():\n    """Doc."""\n{body}\n{table}\n    return T\n'
    assert sizes(source) == [(1 + 1 + 10 + 1, "f:1")]


def test_no_function_in_src_reaches_80_lines():
    too_long = []
    for path in sorted((ROOT / "src").rglob("*.py")):
        for size, where in sizes(path.read_text()):
            if size >= LIMIT:
                too_long.append(f"{path.relative_to(ROOT)}:{where} has {size} lines")
    assert not too_long, "\n".join(too_long)
