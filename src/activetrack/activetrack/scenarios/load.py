"""Load and validate scenario files; errors name the field and what is allowed."""

from __future__ import annotations

from pathlib import Path

import yaml
from pydantic import ValidationError

from activetrack.scenarios.schema import Scenario


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message lists every offending field."""


def _describe(err: dict) -> str:
    where = ".".join(str(p) for p in err["loc"]) or "(top level)"
    msg = err["msg"]
    ctx = err.get("ctx") or {}
    if err["type"] == "literal_error" and "expected" in ctx:
        msg = f"must be one of {ctx['expected']}"
    elif err["type"] == "extra_forbidden":
        msg = "unknown field (check the spelling; see docs/scenarios.md)"
    elif err["type"] == "union_tag_invalid" and "expected_tags" in ctx:
        msg = f"must be one of {ctx['expected_tags']}, got {ctx.get('tag')!r}"
    elif "input" in err and not isinstance(err["input"], dict | list):
        msg = f"{msg} (got {err['input']!r})"
    return f"  {where}: {msg}"


def parse_scenario(data: dict, source: str = "<dict>") -> Scenario:
    """Validate a scenario given as a dict (already parsed YAML)."""
    if not isinstance(data, dict):
        raise ScenarioError(f"{source}: a scenario must be a mapping, got {type(data).__name__}")
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        lines = [_describe(e) for e in exc.errors()]
        raise ScenarioError(f"{source}: invalid scenario\n" + "\n".join(lines)) from None


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a YAML scenario file. Raises ScenarioError before anything runs."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read scenario file: {exc.strerror}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ScenarioError(f"{path}: not valid YAML: {exc}") from None
    return parse_scenario(data, str(path))


def with_tracker_overrides(scenario: Scenario, **overrides) -> Scenario:
    """The scenario with tracker settings replaced (None values are ignored), re-validated."""
    changes = {k: v for k, v in overrides.items() if v is not None}
    if not changes:
        return scenario
    data = scenario.model_dump()
    data["tracker"].update(changes)
    return parse_scenario(data, f"{scenario.name} (tracker overrides {changes})")
