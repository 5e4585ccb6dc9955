"""No code branches on what a sensor, filter or motion model is; the registries and the models
answer every such question.

Each sensor and motion model owns its maths behind the contracts of ``activetrack.models.base``
(``sensor.linearize``, ``sensor.log_likelihood``, ``sensor.fisher_information``,
``model.state_is_pv``, ...), and the registries (``scenarios.registry``, ``filters.registry``,
``planning.criteria``) decide which kinds and names exist. A test of a concrete class, a sensor
kind or a filter name elsewhere would silently send a plugin, or a subclass of a built-in
sensor, down a slow or wrong path; this test reads the source (AST) so such a test cannot come
back.

- filters/ and bounds/ (the maths every sensor goes through): no class, kind or state-name
  test at all (``dispatch_violations``);
- the whole core and ``activetrack_ros``: no class switch on a model class and no kind or
  filter-name test (``kind_violations``); models/ may test its own classes, and the registries
  read a class's ``kind`` (that is their job). ``ALLOWED`` lists the places that still ask,
  file by file, each with its reason.
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


def _class_operands(node: ast.expr) -> list[ast.expr]:
    """The classes of ``isinstance``'s second argument: a tuple's entries, a union's members
    (``A | B``) or the one class."""
    if isinstance(node, ast.Tuple):
        return [c for e in node.elts for c in _class_operands(e)]
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitOr):
        return _class_operands(node.left) + _class_operands(node.right)
    return [node]


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
                hit = {_terminal_name(e) for e in _class_operands(node.args[1])} & classes
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


# --- the whole core and activetrack_ros --------------------------------------------------------

SRC = CORE.parents[1]
ROS = SRC / "activetrack_ros" / "activetrack_ros"
# Where a kind is decided, and where the models test their own classes.
REGISTRIES = ("scenarios/registry.py", "filters/registry.py", "planning/criteria.py")
OWN_CLASSES = ("models/",)


def _registered_names() -> set[str]:
    """The built-in sensor kinds and filter names. "bearing" (and "range") also name planner
    criteria and measurement components, so such a literal alone is no kind test (a comparison
    with ``kind`` is caught as one all the same)."""
    from activetrack.filters.registry import built_in_filters
    from activetrack.planning.criteria import criterion_names
    from activetrack.scenarios import registered_kinds, sensor_kind

    kinds = {
        k
        for k in registered_kinds()
        if sensor_kind(k).sensor_class.__module__.startswith(CORE.name)
    }
    return (kinds | set(built_in_filters())) - set(criterion_names())


NAMES = _registered_names()


def _is_kind_name(node: ast.expr) -> bool:
    """``kind``, ``x.kind``, ``kinds``, ``_BEARING_KINDS``, ``sensor_kinds``: a sensor kind."""
    name = (_terminal_name(node) or "").lower()
    return name in ("kind", "kinds") or name.endswith("_kinds")


def kind_violations(
    source: str, classes: set[str], names: set[str], own: bool = False
) -> list[str]:
    """Every class switch on a model class (not in ``own`` models/), kind test and test of a
    registered kind or filter name in ``source``, as ``line: what``."""
    out = []
    for node in ast.walk(ast.parse(source)):
        line = getattr(node, "lineno", 0)
        if isinstance(node, ast.Compare):
            operands = [node.left, *node.comparators]
            hit = {_terminal_name(o) for o in operands} & classes
            if hit and not own:
                out.append(f"{line}: compared with {sorted(hit)}")
            if any(_is_kind_name(o) for o in operands):
                out.append(f"{line}: a sensor kind compared")
            constants = set().union(*(_strings(o) for o in operands))
            if constants & names:
                out.append(f"{line}: kind or filter name {sorted(constants & names)} compared")
        elif isinstance(node, ast.Call):
            func = _terminal_name(node.func)
            if func in ("isinstance", "issubclass") and len(node.args) == 2 and not own:
                hit = {_terminal_name(e) for e in _class_operands(node.args[1])} & classes
                if hit:
                    out.append(f"{line}: {func}(..., {sorted(hit)})")
            if func in ("getattr", "hasattr") and len(node.args) >= 2:
                if _strings(node.args[1]) & {"kind"}:
                    out.append(f"{line}: {func}(..., {ast.unparse(node.args[1])})")
        elif isinstance(node, ast.match_case) and not own:
            for pattern in ast.walk(node.pattern):
                if isinstance(pattern, ast.MatchClass) and _terminal_name(pattern.cls) in classes:
                    out.append(f"{line}: case {ast.unparse(pattern.cls)}()")
        elif isinstance(node, ast.Tuple | ast.List | ast.Set):
            listed = _strings(node)
            if listed and listed <= names and len(listed) == len(node.elts):
                out.append(f"{line}: a list of kind or filter names {sorted(listed)}")
    return sorted(set(out), key=lambda v: (int(v.split(":")[0]), v))


def _wide_files() -> dict[str, Path]:
    files = {str(p.relative_to(CORE)): p for p in CORE.rglob("*.py")}
    files |= {f"activetrack_ros/{p.relative_to(ROS)}": p for p in ROS.rglob("*.py")}
    return {k: v for k, v in sorted(files.items()) if k not in REGISTRIES}


WIDE = _wide_files()

# Kind questions still asked, file by file: what is asked (the line at this writing). The test
# fails when a file asks another question, or no longer asks one listed here (then remove it).
ALLOWED: dict[str, tuple[str, ...]] = {
    # A scan message's sensor_kind checked against the scenario's sensor (validation of the
    # message, not a question about what the sensor is).
    "activetrack_ros/convert.py": ("a sensor kind compared",),  # :363 msg.sensor_kind
}


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
        "ok = isinstance(sensor, BearingSensor | AmbiguousBearingSensor)",
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


@pytest.mark.parametrize("name", list(WIDE))
def test_no_class_switch_or_kind_test_anywhere(name):
    found = kind_violations(WIDE[name].read_text(), CLASSES, NAMES, name.startswith(OWN_CLASSES))
    allowed = sorted(ALLOWED.get(name, ()))
    assert sorted(v.split(": ", 1)[1] for v in found) == allowed, (
        f"{name} asks what a sensor or filter is: {found} (allowed: {allowed})"
    )


@pytest.mark.parametrize(
    "snippet",
    [
        'if cfg.filter == "ekf": pass',
        'FILTERS = ("ekf", "pf")',
        'INITIATING_KINDS = ("range_bearing",)',
        "match sensor:\n    case RangeBearingSensor(): pass",
        "ok = isinstance(sensor, RangeBearingSensor)",
        'ok = hasattr(sensor, "kind")',
        "ok = sensor.kind in CLUTTER_KINDS",
        'ok = kinds.get(sid) != "range_bearing"',
    ],
)
def test_the_wide_guard_catches_kind_questions(snippet):
    assert kind_violations(snippet, CLASSES, NAMES), snippet


def test_the_wide_guard_lets_other_vocabulary_pass():
    """Criterion names, measurement components and the planner's own settings are no kinds."""
    for snippet in (
        'if criterion == "bearing": pass',
        'ok = tuple(sensor.components) == ("bearing",)',
        'if self.cost_kind == "pcrlb": pass',
        'if cfg.search == "cautious": pass',
    ):
        assert not kind_violations(snippet, CLASSES, NAMES), snippet
    assert {"range_bearing", "ambiguous_bearing", "ekf", "pf"} <= NAMES
    assert "activetrack_ros/convert.py" in WIDE and "scenarios/rules.py" in WIDE
    assert not set(REGISTRIES) & set(WIDE)
