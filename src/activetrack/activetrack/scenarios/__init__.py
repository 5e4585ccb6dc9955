"""Scenario files, in layers: the field types and schema (``fields``, ``schema``: the file's
data; ``tracking``: the tracker-only configuration), the sensor-kind registry
(``registry``), the rules that ask the registries and the components (``rules``), the
builders of the core objects (``build``) and the loader (``load``: parse, schema, rules).
Importing this package registers the built-in sensor kinds."""

from activetrack.scenarios.build import build_motion_model, build_sensor
from activetrack.scenarios.fields import SensorConfigBase
from activetrack.scenarios.load import (
    ScenarioError,
    first_epochs,
    load_scenario,
    load_tracking,
    parse_scenario,
    parse_tracking,
    with_changes,
    with_tracker_overrides,
)
from activetrack.scenarios.registry import (
    SensorKind,
    register_sensor,
    registered_kinds,
    sensor_kind,
    unregister_sensor,
)
from activetrack.scenarios.schema import Scenario
from activetrack.scenarios.tracking import TrackingConfig, tracking_of

__all__ = [
    "Scenario",
    "ScenarioError",
    "SensorConfigBase",
    "SensorKind",
    "TrackingConfig",
    "build_motion_model",
    "build_sensor",
    "first_epochs",
    "load_scenario",
    "load_tracking",
    "parse_scenario",
    "parse_tracking",
    "register_sensor",
    "registered_kinds",
    "sensor_kind",
    "tracking_of",
    "unregister_sensor",
    "with_changes",
    "with_tracker_overrides",
]
