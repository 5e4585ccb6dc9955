"""activetrack core: ROS-free models, sensors, filters, bounds and planning.

The notebook API (docs/api.md)::

    import activetrack as at
    sc = at.load_scenario("scenarios/default.yaml")
    res = at.run_batch(sc, runs=20, jobs=2)   # BatchSummary: arrays, .table(), .to_csv()

This package never imports rclpy; the ROS nodes are thin wrappers around it. Importing it
changes no process-wide setting: the glibc allocator tuning that makes planning and particle
filtering faster (activetrack.allocator) is opt-in; the command line and the nodes turn it on.
The names below are imported on first use, so ``import activetrack`` stays cheap.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

# Public name -> module that defines it.
_EXPORTS = {
    "load_scenario": "activetrack.scenarios",
    "Scenario": "activetrack.scenarios",
    "ScenarioError": "activetrack.scenarios",
    "run_batch": "activetrack.closed_loop.batch",
    "run_once": "activetrack.closed_loop.loop",
    "BatchSummary": "activetrack.closed_loop.batch",
    "RunRecord": "activetrack.closed_loop.record",
    "parallel_map": "activetrack.montecarlo",
    "register_sensor": "activetrack.scenarios.registry",
    "register_filter": "activetrack.filters.registry",
    "register_criterion": "activetrack.planning.criteria",
    "ospa": "activetrack.metrics",
    "gospa": "activetrack.metrics",
    "GospaResult": "activetrack.metrics",
    "ospa_over_time": "activetrack.metrics",
    "gospa_over_time": "activetrack.metrics",
}

__all__ = [
    "BatchSummary",
    "GospaResult",
    "RunRecord",
    "Scenario",
    "ScenarioError",
    "__version__",
    "gospa",
    "gospa_over_time",
    "load_scenario",
    "ospa",
    "ospa_over_time",
    "parallel_map",
    "register_criterion",
    "register_filter",
    "register_sensor",
    "run_batch",
    "run_once",
]

if TYPE_CHECKING:
    from activetrack.closed_loop.batch import BatchSummary, run_batch
    from activetrack.closed_loop.loop import run_once
    from activetrack.closed_loop.record import RunRecord
    from activetrack.filters.registry import register_filter
    from activetrack.metrics import GospaResult, gospa, gospa_over_time, ospa, ospa_over_time
    from activetrack.montecarlo import parallel_map
    from activetrack.planning.criteria import register_criterion
    from activetrack.scenarios import Scenario, ScenarioError, load_scenario
    from activetrack.scenarios.registry import register_sensor


def __getattr__(name: str) -> Any:
    try:
        module = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'activetrack' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
