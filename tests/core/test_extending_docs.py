"""docs/extending.md shows what the tests run (the markers: tests/doc_blocks.py).

Python blocks: every statement but the imports is a statement of the test file named in the
marker (compared as syntax trees), and the block imports and runs as a module (its
registrations are undone afterwards). Scenario blocks: the text of the test's constant.
Command blocks: commands the ``activetrack`` parser accepts, on the page's scenario files.
"""

from __future__ import annotations

import ast
import importlib
import shlex
import sys

import pytest
from doc_blocks import ROOT, Block, blocks, fences

from activetrack.filters import filter_names, unregister_filter
from activetrack.planning.criteria import criterion_names, unregister_criterion
from activetrack.scenarios import registered_kinds, unregister_sensor
from activetrack_bringup.cli import build_parser

BLOCKS = blocks()
PYTHON = [b for b in BLOCKS if b.lang == "python"]
YAML = [b for b in BLOCKS if b.lang == "yaml"]
CONSOLE = [b for b in BLOCKS if b.lang == "console"]


def _id(block: Block) -> str:
    return block.file or f"line-{block.line}"


def _statements(path) -> set[str]:
    """Every statement of a file, nested ones included, as a syntax tree dump."""
    tree = ast.parse(path.read_text())
    return {ast.dump(node) for node in ast.walk(tree) if isinstance(node, ast.stmt)}


def _is_docstring(stmt: ast.stmt) -> bool:
    return isinstance(stmt, ast.Expr) and isinstance(getattr(stmt, "value", None), ast.Constant)


def _constant(path, name: str) -> str:
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Assign) and [ast.unparse(t) for t in node.targets] == [name]:
            return ast.literal_eval(node.value)
    raise LookupError(f"{path} has no constant {name}")


def test_every_code_block_is_marked():
    assert len(BLOCKS) == fences() >= 7
    assert {b.lang for b in BLOCKS} == {"python", "yaml", "console"}
    assert {b.file for b in BLOCKS if b.file} >= {"my_sensors.py", "my_filters.py"}


@pytest.mark.parametrize("block", PYTHON, ids=_id)
def test_python_block_is_the_tests_code(block):
    path = ROOT / block.against
    known = _statements(path)
    for stmt in ast.parse(block.code).body:
        if isinstance(stmt, ast.Import | ast.ImportFrom) or _is_docstring(stmt):
            continue
        where = f"docs/extending.md line {block.line + stmt.lineno + 1}"
        assert ast.dump(stmt) in known, f"{where}: {ast.unparse(stmt)[:70]!r} not in {path.name}"


@pytest.mark.parametrize("block", PYTHON, ids=_id)
def test_python_block_runs_as_a_module(block, tmp_path, monkeypatch):
    """Imported as a plugin module would be; what it registers is taken away again."""
    name = f"extending_docs_block_{block.line}"
    (tmp_path / f"{name}.py").write_text(block.code)
    monkeypatch.syspath_prepend(str(tmp_path))
    kinds, filters, criteria = registered_kinds(), filter_names(), criterion_names()
    try:
        importlib.import_module(name)
    finally:
        sys.modules.pop(name, None)
        for kind in set(registered_kinds()) - set(kinds):
            unregister_sensor(kind)
        for filter_name in set(filter_names()) - set(filters):
            unregister_filter(filter_name)
        for criterion in set(criterion_names()) - set(criteria):
            unregister_criterion(criterion)
    added = (registered_kinds() != kinds, filter_names() != filters, criterion_names() != criteria)
    assert added == (False, False, False)


@pytest.mark.parametrize("block", YAML, ids=_id)
def test_scenario_block_is_the_tests_scenario(block):
    path, constant = block.against.split()
    assert block.code == _constant(ROOT / path, constant)


@pytest.mark.parametrize("block", CONSOLE, ids=_id)
def test_commands_are_accepted_by_the_command_line(block):
    assert block.against == "the command line"
    scenarios = {b.file for b in YAML}
    lines = [line for line in block.code.splitlines() if line.strip()]
    for line in lines:
        words = shlex.split(line)
        while "=" in words[0]:  # environment assignments
            words.pop(0)
        assert words[0] == "activetrack", line
        args = build_parser().parse_args(words[1:])
        assert args.scenario in scenarios, line
