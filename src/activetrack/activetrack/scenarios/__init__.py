"""Scenario files: schema, loading with clear errors, the sensor-kind registry and builders for
the core objects."""

from activetrack.scenarios.build import build_motion_model, build_sensor
from activetrack.scenarios.load import (
    ScenarioError,
    load_scenario,
    parse_scenario,
    with_tracker_overrides,
)
from activetrack.scenarios.registry import (
    SensorKind,
    register_sensor,
    registered_kinds,
    sensor_kind,
    unregister_sensor,
)
from activetrack.scenarios.schema import Scenario, SensorConfigBase

__all__ = [
    "Scenario",
    "ScenarioError",
    "SensorConfigBase",
    "SensorKind",
    "build_motion_model",
    "build_sensor",
    "load_scenario",
    "parse_scenario",
    "register_sensor",
    "registered_kinds",
    "sensor_kind",
    "unregister_sensor",
    "with_tracker_overrides",
]
