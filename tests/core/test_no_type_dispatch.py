"""filters/ and bounds/ never branch on what a sensor or motion model is.

Each sensor and motion model owns its maths behind the contracts of ``activetrack.models.base``
(``sensor.linearize``, ``sensor.log_likelihood``, ``sensor.fisher_information``,
``model.state_is_pv``, ...). A test of a concrete class, a sensor kind or a state name in the
consumers would silently send a new sensor down a slow or wrong path, or a subclass of a
built-in one down another; this test reads the source (AST) so such a test cannot come back.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import activetrack

CORE = Path(activetrack.__file__).parent
CHECKED = ("filters", "bounds")
# Names of the state entries of every motion model (``state_names``) and of the pv vector.
STATE_NAMES = {"x", "xdot", "y", "ydot", "psi", "px", "py", "omega", "v"}


def _model_classes() -> set[str]:
    """Classes defined in activetrack/models/ that are not contracts (Protocols)."""
    names = set()
    for path in (CORE / "models").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef):
                bases = {ast.unparse(b) for b in node.bases}
                if not any(b.endswith("Protocol") for b in bases):
                    names.add(node.name)
    return names


def _terminal_name(node: ast.expr) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return None


def _is_type_call(node: ast.expr) -> bool:
    return isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "type"


def _strings(node: ast.expr) -> set[str]:
    """String constants of a literal, or of a tuple / list / set literal."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return {node.value}
    if isinstance(node, ast.Tuple | ast.List | ast.Set):
        return {s for e in node.elts for s in _strings(e)}
    return set()


def dispatch_violations(source: str, classes: set[str]) -> list[str]:
    """Every class, kind or state-name test in ``source``, as ``line: what``."""
    out = []
    for node in ast.walk(ast.parse(source)):
        line = getattr(node, "lineno", 0)
        if isinstance(node, ast.Compare):
            operands = [node.left, *node.comparators]
            if any(_is_type_call(o) for o in operands):
                out.append(f"{line}: type(...) compared")
            hit = {_terminal_name(o) for o in operands} & classes
            if hit:
                out.append(f"{line}: compared with {sorted(hit)}")
            names = {(_terminal_name(o) or "").lower() for o in operands}
            if any("kind" in n for n in names):  # kind == ..., x in _BEARING_KINDS
                out.append(f"{line}: a sensor kind compared")
            if "state_names" in names:
                out.append(f"{line}: state names compared")
            constants = set().union(*(_strings(o) for o in operands))
            if constants & STATE_NAMES:
                out.append(f"{line}: state name {sorted(constants & STATE_NAMES)} compared")
        elif isinstance(node, ast.Call):
            func = _terminal_name(node.func)
            if func in ("isinstance", "issubclass") and len(node.args) == 2:
                target = node.args[1]
                elts = target.elts if isinstance(target, ast.Tuple) else [target]
                hit = {_terminal_name(e) for e in elts} & classes
                if hit:
                    out.append(f"{line}: {func}(..., {sorted(hit)})")
            if func in ("getattr", "hasattr") and len(node.args) >= 2:
                if _strings(node.args[1]) & {"kind", "state_names"}:
                    out.append(f"{line}: {func}(..., {ast.unparse(node.args[1])})")
        elif isinstance(node, ast.Attribute) and node.attr == "state_names":
            out.append(f"{line}: .state_names read")
        elif isinstance(node, ast.Tuple | ast.List | ast.Set):
            names = _strings(node)
            if len(names) > 1 and names <= STATE_NAMES:
                out.append(f"{line}: a tuple of state names {sorted(names)}")
    return sorted(set(out))


CLASSES = _model_classes()
FILES = sorted(p for folder in CHECKED for p in (CORE / folder).glob("*.py"))


@pytest.mark.parametrize("path", FILES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_no_class_kind_or_state_name_dispatch(path):
    found = dispatch_violations(path.read_text(), CLASSES)
    assert not found, f"{path.relative_to(CORE)} branches on a sensor or model: {found}"


@pytest.mark.parametrize(
    "snippet",
    [
        "fast = type(sensor) is BearingSensor",
        "fast = type(sensor) in _FAST_SENSORS",
        "cls = type(sensor)\nfast = cls is not BearingSensor",
        "ok = isinstance(sensor, (BearingSensor, RangeBearingSensor))",
        "ok = issubclass(type(model), NearlyConstantVelocity)",
        "pv = tuple(model.state_names) == PV_NAMES",
        'PV_NAMES = ("x", "xdot", "y", "ydot")',
        'bearing = getattr(sensor, "kind", "") in _BEARING_KINDS',
        "bearing = sensor.kind in _BEARING_KINDS",
        'bearing = kind == "range_bearing"',
        'if "bearing" in kinds: pass',
    ],
)
def test_the_guard_catches_the_old_dispatch(snippet):
    """The patterns filters/ and bounds/ used before the sensors owned their maths."""
    assert dispatch_violations(snippet, CLASSES), snippet


def test_the_guard_sees_the_model_classes_and_files():
    assert {"BearingSensor", "RangeBearingSensor", "NearlyConstantVelocity"} <= CLASSES
    assert "SensorModel" not in CLASSES and "MotionModel" not in CLASSES
    assert {"ekf.py", "particle.py", "pcrlb.py", "tichavsky.py"} <= {p.name for p in FILES}
