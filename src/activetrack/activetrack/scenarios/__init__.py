"""Scenario files: schema, loading with clear errors, and builders for the core objects."""

from activetrack.scenarios.build import build_motion_model, build_sensor
from activetrack.scenarios.load import (
    ScenarioError,
    load_scenario,
    parse_scenario,
    with_tracker_overrides,
)
from activetrack.scenarios.schema import Scenario

__all__ = [
    "Scenario",
    "ScenarioError",
    "build_motion_model",
    "build_sensor",
    "load_scenario",
    "parse_scenario",
    "with_tracker_overrides",
]
