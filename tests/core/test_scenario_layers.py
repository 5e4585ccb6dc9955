"""The scenario package in layers: the schema checks the file's shape, the rules (run by the
loader) everything that asks a registry or a component, and a changed scenario goes through both
(``with_changes``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from activetrack.scenarios import (
    Scenario,
    ScenarioError,
    first_epochs,
    load_scenario,
    parse_scenario,
    with_changes,
)
from activetrack.scenarios.rules import name_problems, scenario_problems

ROOT = Path(__file__).resolve().parents[2]
DEFAULT = ROOT / "scenarios" / "default.yaml"
APPEAR = ROOT / "scenarios" / "mt_appear_disappear.yaml"


def _default() -> dict:
    return yaml.safe_load(DEFAULT.read_text())


def test_the_schema_checks_the_shape_and_the_loader_the_rules():
    data = _default()
    data["planner"]["search"] = "cautious"  # a shape the schema accepts, a rule refuses
    shaped = Scenario.model_validate(data)
    assert scenario_problems(shaped) == [
        (
            "planner.search",
            "'cautious' needs exactly one controllable platform (the robot), got 2: ['p1', 'p2']",
        )
    ]
    with pytest.raises(ScenarioError) as info:
        parse_scenario(data, "cautious.yaml")
    assert str(info.value).splitlines() == [
        "cautious.yaml: invalid scenario",
        *(f"  {field}: {message}" for field, message in scenario_problems(shaped)),
    ]


def test_an_unregistered_name_is_reported_with_the_schemas_errors():
    data = _default()
    data["tracker"]["filter"] = "ukf"
    data["planner"]["selection"] = {"criterion": "nope"}
    data["dt"] = -1.0
    assert name_problems(data) == [
        ("tracker.filter", "must be one of 'ekf' or 'pf', got 'ukf'"),
        (
            "planner.selection.criterion",
            "must be one of 'det_pos', 'heading', 'range', 'doppler' or 'bearing'",
        ),
    ]
    with pytest.raises(ScenarioError) as info:
        parse_scenario(data, "x.yaml")
    lines = str(info.value).splitlines()
    assert lines[1].startswith("  dt: Input should be greater than or equal to")
    assert lines[2:] == [
        "  tracker.filter: must be one of 'ekf' or 'pf', got 'ukf'",
        "  planner.selection.criterion: must be one of 'det_pos', 'heading', 'range', "
        "'doppler' or 'bearing'",
    ]
    # Absent and non-text entries are the schema's business.
    assert name_problems({"tracker": {"filter": 3}, "planner": "x"}) == []


def test_with_changes_validates_a_variant_like_a_file():
    s = load_scenario(APPEAR)
    short = with_changes(s, steps=40, planner={"targets": {"assignment": "random"}})
    assert (short.steps, short.planner.targets.assignment) == (40, "random")
    assert short.planner.targets.aggregate == s.planner.targets.aggregate  # merged, not replaced
    assert short.model_dump() == {
        **s.model_dump(),
        "steps": 40,
        "planner": {
            **s.model_dump()["planner"],
            "targets": {**s.model_dump()["planner"]["targets"], "assignment": "random"},
        },
    }
    assert with_changes(s) is s
    with pytest.raises(ScenarioError, match=r"  steps: Input should be greater than or equal"):
        with_changes(s, steps=0)
    # A rule, not the shape: a target born after the last epoch.
    with pytest.raises(ScenarioError, match=r"  targets\.\d\.birth: must be < steps \(5\)"):
        with_changes(s, steps=5)


def test_first_epochs_cuts_a_valid_scenario_without_the_birth_rule():
    s = load_scenario(APPEAR)
    cut = first_epochs(s, 5)
    assert cut.steps == 5 and cut.targets == s.targets
    assert first_epochs(s, s.steps) == s
    for bad in (0, s.steps + 1, 2.0, True):
        with pytest.raises(ValueError, match=rf"steps must be an integer in \[1, {s.steps}\]"):
            first_epochs(s, bad)


def test_the_schema_alone_has_the_built_in_sensor_kinds():
    """Importing the schema module runs the package's __init__, which registers the built-in
    kinds (scenarios.build): a fresh process validates a file's sensors at once."""
    code = (
        "import yaml\n"
        "from activetrack.scenarios.schema import Scenario\n"
        f"s = Scenario.model_validate(yaml.safe_load(open({str(DEFAULT)!r}).read()))\n"
        "print(type(s.platforms[0].sensors[0]).__name__)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "BearingSensorConfig"


def test_a_file_read_again_is_parsed_once_and_a_changed_one_again(tmp_path, monkeypatch):
    """The runner and its nodes in one process read one file four times: the YAML of the same
    text is parsed once, each reader gets its own copy, and a changed file is parsed anew."""
    from activetrack.scenarios import load

    changed = _default()
    parses = []
    real = load.yaml.safe_load
    monkeypatch.setattr(load.yaml, "safe_load", lambda text: parses.append(1) or real(text))
    path = tmp_path / "s.yaml"
    path.write_text(DEFAULT.read_text())
    first, second = load_scenario(path), load_scenario(path)
    assert first == second and len(parses) == 1
    _, data = load._read_yaml(path)
    data["steps"] = 3  # a reader's copy: the next reader's is the file's
    assert load._read_yaml(path)[1]["steps"] == first.steps != 3 and len(parses) == 1
    path.write_text(yaml.safe_dump(changed | {"steps": first.steps + 1}))
    assert load_scenario(path).steps == first.steps + 1 and len(parses) == 2
