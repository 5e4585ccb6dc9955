"""Builders: the core objects a validated scenario describes.

Motion models, sensors (alone, or in clutter with their field of view) and the planner's
inputs (platforms, limits, search and plan settings). The components take these objects; the
scenario file's shape stays here. The built-in sensor kinds are registered below, with the
same call a plugin makes (:func:`activetrack.scenarios.registry.register_sensor`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, cast

import numpy as np

from activetrack.arraytypes import ArrayLike
from activetrack.models.base import MotionModel, SensorModel
from activetrack.models.motion import (
    CircularMotion,
    CircularMotionKnownOmega,
    ConstantTurn,
    NearlyConstantVelocity,
    NearlyConstantVelocityDiscrete,
)
from activetrack.models.sensors import (
    AmbiguousBearingSensor,
    BearingSensor,
    RangeBearingSensor,
    RangeRateBearingSensor,
)
from activetrack.planning import PlannerPlatform, PlanSettings, PlatformLimits, SearchSettings
from activetrack.scenarios.fields import SensorConfigBase
from activetrack.scenarios.registry import register_sensor, sensor_kind
from activetrack.scenarios.schema import (
    AmbiguousBearingSensorConfig,
    BearingSensorConfig,
    ManoeuvreLimits,
    MotionConfig,
    PlannerConfig,
    PlatformConfig,
    RangeBearingSensorConfig,
    RangeRateBearingSensorConfig,
    Scenario,
)

__all__ = [
    "build_motion_model",
    "build_sensor",
    "plan_settings",
    "planner_platforms",
    "platform_limits",
    "search_settings",
    "steered_limits",
]

# The built-in kinds, registered like any other (the order is that of the error messages).
register_sensor(BearingSensor, BearingSensorConfig)
register_sensor(AmbiguousBearingSensor, AmbiguousBearingSensorConfig)
register_sensor(RangeBearingSensor, RangeBearingSensorConfig)
register_sensor(RangeRateBearingSensor, RangeRateBearingSensorConfig)


# The class of each motion block's model, built from the block's other fields.
_MOTION_MODELS: dict[str, Callable[..., MotionModel]] = {
    "ncv": NearlyConstantVelocity,
    "ncv_discrete": NearlyConstantVelocityDiscrete,
    "constant_turn": ConstantTurn,
    "circular": CircularMotion,
    "circular_known_omega": CircularMotionKnownOmega,
}


def build_motion_model(cfg: MotionConfig) -> MotionModel:
    """The motion model object a ``motion:`` block describes."""
    if cfg.model not in _MOTION_MODELS:
        raise ValueError(f"motion.model: unknown {cfg.model!r}")
    return _MOTION_MODELS[cfg.model](**cfg.model_dump(exclude={"model"}))


def build_sensor(cfg: SensorConfigBase) -> SensorModel:
    """The sensor object a validated ``sensors:`` entry describes (its registered kind's
    ``build``)."""
    return cast(SensorModel, sensor_kind(cfg.kind).build(cfg))


# --- the planner's inputs ----------------------------------------------------------------------


def platform_limits(cfg: ManoeuvreLimits, dt: float) -> PlatformLimits:
    """A platform's ``limits:`` (either pair, Hernandez or Ramdaras) for decisions ``dt``
    seconds apart (activetrack.planning.manoeuvre: dv_max = a_max T, dpsi_max = psi_rate_max T)."""
    dpsi_max, dv_max = cfg.per_epoch(dt)
    return PlatformLimits(min(float(dpsi_max), math.pi), float(dv_max), cfg.v_min, cfg.v_max)


def steered_limits(cfg: PlatformConfig, dt: float) -> PlatformLimits | None:
    """A controllable platform's limits per epoch (:func:`platform_limits`); None otherwise."""
    return platform_limits(cfg.limits, dt) if cfg.controllable and cfg.limits is not None else None


def search_settings(cfg: PlannerConfig, **overrides: Any) -> SearchSettings:
    """The search of a ``planner:`` block; keyword ``overrides`` replace any field."""
    names = ("search", "grid_size", "quadrant_divisions", "quadrant_patience", "sector_levels")
    return SearchSettings(**({name: getattr(cfg, name) for name in names} | overrides))


def plan_settings(cfg: PlannerConfig, **overrides: Any) -> PlanSettings:
    """The PCRLB planner's settings of a ``planner:`` block; keyword ``overrides`` replace
    fields of :class:`PlanSettings` or of :class:`SearchSettings` (e.g. ``horizon=2``,
    ``search="grid"``, ``grid_size=21``)."""
    if getattr(cfg, "cost", "pcrlb") != "pcrlb":
        raise ValueError(f"planner.cost must be 'pcrlb' for this planner, got {cfg.cost!r}")
    search_fields = set(SearchSettings.__dataclass_fields__)
    search: dict[str, Any] = {}
    top: dict[str, Any] = {
        "criterion": cfg.criterion,
        "horizon": cfg.horizon,
        "max_sensor_iterations": cfg.max_sensor_iterations,
    }
    for key, value in overrides.items():
        if key in search_fields:
            search[key] = value
        elif key in top:
            top[key] = value
        else:
            raise ValueError(f"overrides: unknown setting {key!r}")
    return PlanSettings(search=search_settings(cfg, **search), **top)


def planner_platforms(
    scenario: Scenario, states: Mapping[str, ArrayLike] | None = None
) -> list[PlannerPlatform]:
    """The planner's platforms of a scenario (limits per epoch of ``scenario.dt``);
    ``states`` maps platform id to a pv overriding the initial state."""
    out = []
    for cfg in scenario.platforms:
        pv = cfg.initial_state if states is None or cfg.id not in states else states[cfg.id]
        sensors = tuple(build_sensor(s) for s in cfg.sensors)
        limits = steered_limits(cfg, scenario.dt)
        out.append(PlannerPlatform(cfg.id, np.asarray(pv, float), sensors, limits))
    return out
