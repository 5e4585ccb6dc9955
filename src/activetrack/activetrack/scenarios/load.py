"""Load and validate scenario files; errors name the field and what is allowed.

Whatever a file holds, :func:`load_scenario` returns a valid :class:`Scenario` or raises
:class:`ScenarioError` with a short reason: unreadable, too large, not UTF-8, not YAML, nested
too deeply, an alias bomb, not a mapping, a ``plugins`` entry that cannot be imported, or the
list of invalid fields. Validation is parse, then the schema (:mod:`.schema`: the file's
shape), then the rules (:mod:`.rules`: names the registries hold, rules across sections); a
changed scenario (:func:`with_changes`) and a tracker-only configuration (:func:`load_tracking`,
:func:`parse_tracking`) go the same way. A file's ``plugins:`` are imported before its other
fields are validated: a scenario file that names plugins is as trusted as a Python script
(docs/extending.md).
"""

from __future__ import annotations

import copy
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError
from pydantic_core import ErrorDetails

from activetrack.scenarios.fields import shown
from activetrack.scenarios.plugins import PluginError, import_plugins
from activetrack.scenarios.rules import (
    Problems,
    name_problems,
    scenario_problems,
    tracking_problems,
)
from activetrack.scenarios.schema import Scenario
from activetrack.scenarios.tracking import TrackingConfig, tracking_of

Configured = TypeVar("Configured", Scenario, TrackingConfig)

# A scenario file is a few kB; these bound what a malformed or hostile one can cost.
MAX_FILE_BYTES = 1 << 20  # 1 MiB
MAX_NESTING = 32  # levels of YAML collections (a scenario uses 5)
MAX_NODES = 100_000  # YAML nodes with every alias expanded (a scenario has a few hundred)
MAX_ERROR_LINES = 20  # invalid fields listed before "... and N more"

_FIELD_MESSAGE = re.compile(r"([A-Za-z_][\w.]*): (.+)", re.DOTALL)


# "targets.0" as a field name (at the start of an error line, or after a space: messages name
# fields too), and what follows it.
_ONE_TARGET = re.compile(r"(^|\s)targets\.0(\.|:|\b)")


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message lists every offending field."""


def _describe(err: ErrorDetails) -> list[str]:
    """Lines ``  field: message`` for one pydantic error."""
    loc = [str(p) for p in err["loc"]]
    msg = err["msg"]
    ctx = err.get("ctx") or {}
    if err["type"] == "value_error":
        # Our validators' messages: one rule per line, each "field: message" relative to loc.
        lines = []
        for line in str(ctx.get("error", msg)).splitlines():
            m = _FIELD_MESSAGE.fullmatch(line)
            where = ".".join([*loc, m.group(1)]) if m else ".".join(loc)
            lines.append(f"  {where or '(top level)'}: {m.group(2) if m else line}")
        return lines
    if err["type"] == "literal_error" and "expected" in ctx:
        msg = f"must be one of {ctx['expected']}"
    elif err["type"] == "extra_forbidden":
        msg = "unknown field (check the spelling; the fields: activetrack/scenarios/schema.py)"
    elif err["type"] == "union_tag_invalid" and "expected_tags" in ctx:
        msg = f"must be one of {ctx['expected_tags']}, got {shown(ctx.get('tag'))}"
    elif "input" in err and not isinstance(err["input"], dict | list):
        msg = f"{msg} (got {shown(err['input'])})"
    return [f"  {'.'.join(loc) or '(top level)'}: {msg}"]


def _lines(problems: list[tuple[str, str]]) -> list[str]:
    """``  field: message`` per rule problem, as the schema's errors read."""
    return [f"  {field}: {message}" for field, message in problems]


def _as_written(lines: list[str], data: dict) -> list[str]:
    """Error lines naming the fields as the file does: a file that gives its one target as
    ``target:`` reads ``target.prior`` where the scenario says ``targets.0.prior``."""
    if "target" not in data or "targets" in data:
        return lines
    return [_ONE_TARGET.sub(r"\1target\2", line) for line in lines]


def _validated(
    cls: type[Configured], problems: Callable[[Configured], Problems], data: dict
) -> tuple[Configured | None, list[str]]:
    """``cls`` validated from ``data`` (the schema, then the registered names, then
    ``problems``, the rules across sections) and no error lines, or None and every invalid
    field (:func:`_as_written`)."""
    try:
        model = cls.model_validate(data)
    except ValidationError as exc:
        lines = [line for e in exc.errors() for line in _describe(e)]
        return None, _as_written(lines + _lines(name_problems(data)), data)
    names = name_problems(data)  # the rules across sections need registered names
    lines = _as_written(_lines(names or problems(model)), data)
    return (None, lines) if lines else (model, [])


def parse_scenario(data: object, source: str = "<dict>") -> Scenario:
    """Validate a scenario given as a dict (already parsed YAML): the schema, then the rules.
    Its ``plugins`` are imported first (they may register the sensor kinds, filters and
    criteria the rest names)."""
    return _parse(data, source, "scenario", "name:, dt:, ...", Scenario, scenario_problems)


def _parse(
    data: object,
    source: str,
    what: str,
    fields: str,
    cls: type[Configured],
    problems: Callable[[Configured], Problems],
) -> Configured:
    """``cls`` of ``data`` (:func:`_validated`), or one ScenarioError naming ``source``,
    ``what`` ("scenario", "tracker configuration") and every invalid field; plugins first."""
    if not isinstance(data, dict):
        article = "an" if what[0] in "aeiou" else "a"
        raise ScenarioError(
            f"{source}: {article} {what} must be a mapping of fields ({fields}), "
            f"got {type(data).__name__}"
        )
    if "plugins" in data:
        try:
            import_plugins(data["plugins"])
        except PluginError as exc:
            raise ScenarioError(f"{source}: {exc}") from None
    try:
        model, lines = _validated(cls, problems, data)
    except RecursionError:
        raise ScenarioError(f"{source}: invalid {what}: nested too deeply") from None
    except Exception as exc:  # a check of ours failed unexpectedly: still one clear error
        raise ScenarioError(
            f"{source}: invalid {what} (internal check failed: {type(exc).__name__}: "
            f"{shown(str(exc))})"
        ) from None
    if model is None:
        listed = lines[:MAX_ERROR_LINES]
        if len(lines) > MAX_ERROR_LINES:
            listed.append(f"  ... and {len(lines) - MAX_ERROR_LINES} more")
        raise ScenarioError(f"{source}: invalid {what}\n" + "\n".join(listed))
    return model


def _read_text(path: Path) -> str:
    """The file as text, at most MAX_FILE_BYTES, UTF-8; ScenarioError otherwise."""
    if path.is_dir():
        raise ScenarioError(f"{path}: is a directory, not a scenario file")
    try:
        with path.open("rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read scenario file: {exc.strerror or exc}") from None
    if len(data) > MAX_FILE_BYTES:
        raise ScenarioError(
            f"{path}: too large for a scenario file (more than {MAX_FILE_BYTES} bytes)"
        )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(
            f"{path}: not a UTF-8 text file (byte 0x{data[exc.start]:02x} at offset {exc.start})"
        ) from None
    if not text.strip():
        raise ScenarioError(f"{path}: the file is empty")
    return text


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """One line: what is wrong and where (PyYAML's own message spans several lines)."""
    parts = [getattr(exc, "context", None), getattr(exc, "problem", None)]
    text = "; ".join(str(p) for p in parts if p) or str(exc)
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return f"not valid YAML{where}: {' '.join(text.split())}"


def _check_structure(text: str) -> None:
    """Walk the YAML events (no recursion, no objects built): bound the nesting depth and the
    size with aliases expanded (a "billion laughs" document is a few hundred bytes)."""
    depth = 0
    counts = [0]  # nodes under each open collection, expanded
    open_anchors = [None]  # anchor of each open collection
    anchored: dict[str, int] = {}  # anchor -> expanded size of its node
    for event in yaml.parse(text, Loader=yaml.SafeLoader):
        if isinstance(event, yaml.AliasEvent):
            if event.anchor not in anchored:  # unknown, or the collection it sits in
                raise ScenarioError(f"alias *{event.anchor} refers to itself or to no anchor")
            size = anchored[event.anchor]
        elif isinstance(event, yaml.ScalarEvent):
            size = 1
            if event.anchor is not None:
                anchored[event.anchor] = 1
        elif isinstance(event, yaml.CollectionStartEvent):
            depth += 1
            if depth > MAX_NESTING:
                raise ScenarioError(f"nested deeper than {MAX_NESTING} levels")
            counts.append(1)
            open_anchors.append(event.anchor)
            continue
        elif isinstance(event, yaml.CollectionEndEvent):
            depth -= 1
            size = counts.pop()
            anchor = open_anchors.pop()
            if anchor is not None:
                anchored[anchor] = size
        else:  # stream and document start / end
            continue
        counts[-1] += size
        if counts[-1] > MAX_NODES:
            raise ScenarioError(
                f"more than {MAX_NODES} values once aliases are expanded (an alias bomb?)"
            )


def _read_yaml(path: str | Path) -> tuple[Path, Any]:
    """The parsed YAML of a file (not None); ScenarioError for anything else."""
    try:
        path = Path(path)
    except TypeError:
        raise ScenarioError(f"{path!r}: not a file path") from None
    try:
        text = _read_text(path)
    except ValueError as exc:  # ScenarioError, or a path with a NUL character
        if isinstance(exc, ScenarioError):
            raise
        raise ScenarioError(f"{path}: cannot read scenario file: {exc}") from None
    if _last_parsed is not None and _last_parsed[0] == text:
        return path, copy.deepcopy(_last_parsed[1])
    try:
        _check_structure(text)
        data = yaml.safe_load(text)
    except ScenarioError as exc:
        raise ScenarioError(f"{path}: {exc}") from None
    except yaml.YAMLError as exc:
        raise ScenarioError(f"{path}: {_yaml_problem(exc)}") from None
    except RecursionError:
        raise ScenarioError(f"{path}: nested too deeply") from None
    except Exception as exc:  # the YAML library failed some other way: one clear error
        raise ScenarioError(
            f"{path}: not valid YAML ({type(exc).__name__}: {shown(str(exc))})"
        ) from None
    if data is None:
        raise ScenarioError(f"{path}: the file holds no scenario (only comments)")
    _remember(text, data)
    return path, data


# The last text parsed and its data (kept as parsed): `activetrack run` in one process reads
# its scenario file four times (runner, sim, tracker, planner), 30 ms of YAML each at 30
# targets. Keyed by the whole text, so a changed file is parsed again.
_last_parsed: tuple[str, Any] | None = None


def _remember(text: str, data: Any) -> None:
    global _last_parsed
    _last_parsed = (text, copy.deepcopy(data))


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a YAML scenario file. Raises ScenarioError before anything runs
    (but the file's ``plugins``, imported first), and no other exception, whatever the file
    holds."""
    path, data = _read_yaml(path)
    return parse_scenario(data, str(path))


# --- tracker-only configurations ---------------------------------------------------------------


def parse_tracking(data: object, source: str = "<dict>") -> TrackingConfig:
    """Validate a tracker configuration given as a dict (parsed YAML): the schema
    (:mod:`.tracking`), then the rules; its ``plugins`` are imported first."""
    what, fields = "tracker configuration", "name:, dt:, platforms:, tracker:, ..."
    return _parse(data, source, what, fields, TrackingConfig, tracking_problems)


def load_tracking(path: str | Path) -> TrackingConfig:
    """Read and validate a tracker configuration file, or a scenario file (one with
    ``steps:``), whose tracker it then describes (:func:`~.tracking.tracking_of`).
    ScenarioError, and no other exception, for anything else."""
    path, data = _read_yaml(path)
    if isinstance(data, dict) and "steps" in data:
        return tracking_of(parse_scenario(data, f"{path} (a scenario: it gives steps)"))
    return parse_tracking(data, str(path))


def _merged(base: dict, changes: Mapping[str, Any]) -> dict:
    """``base`` with ``changes``: a mapping merges into a section, anything else replaces."""
    out = dict(base)
    for key, value in changes.items():
        if isinstance(value, BaseModel):
            value = value.model_dump()
        if isinstance(value, Mapping) and isinstance(out.get(key), dict):
            value = _merged(out[key], value)
        out[key] = value
    return out


def with_changes(scenario: Scenario, **changes: Any) -> Scenario:
    """The scenario with ``changes``, validated as a file is (schema and rules; ScenarioError
    naming the fields otherwise). A mapping merges into its section, e.g.
    ``with_changes(s, steps=5, planner={"targets": {"assignment": "random"}})``; a section
    given as a pydantic model, a list or a value replaces the old one."""
    if not changes:
        return scenario
    data = _merged(scenario.model_dump(), changes)
    return parse_scenario(data, f"{scenario.name} (with {shown(changes)})")


def with_tracker_overrides(scenario: Configured, **overrides: object) -> Configured:
    """The scenario (or tracker configuration) with tracker settings replaced (None values are
    ignored), re-validated."""
    changes = {k: v for k, v in overrides.items() if v is not None}
    if not changes:
        return scenario
    data = scenario.model_dump()
    data["tracker"].update(changes)
    source = f"{scenario.name} (tracker overrides {changes})"
    if isinstance(scenario, TrackingConfig):
        return parse_tracking(data, source)
    return parse_scenario(data, source)


def first_epochs(scenario: Scenario, steps: int) -> Scenario:
    """The valid ``scenario`` cut to its first ``steps`` epochs (1 <= steps <= its own), to
    summarise an interrupted run. Not re-validated on purpose: a target born after the cut keeps
    its birth, which a file of ``steps`` epochs could not hold (``targets.i.birth < steps``);
    every other rule holds for the cut scenario as it did for the whole one."""
    if isinstance(steps, bool) or not isinstance(steps, int) or not 1 <= steps <= scenario.steps:
        raise ValueError(f"steps must be an integer in [1, {scenario.steps}], got {steps!r}")
    return scenario.model_copy(update={"steps": steps})
