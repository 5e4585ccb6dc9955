"""Build core objects (motion models, sensors) from validated scenario configuration."""

from __future__ import annotations

from typing import TYPE_CHECKING

from activetrack.models.base import MotionModel
from activetrack.models.motion import (
    CircularMotion,
    CircularMotionKnownOmega,
    ConstantTurn,
    NearlyConstantVelocity,
    NearlyConstantVelocityDiscrete,
)
from activetrack.scenarios.registry import build_sensor
from activetrack.scenarios.schema import (
    CircularKnownOmegaMotion,
    CircularMotionConfig,
    ConstantTurnMotion,
    MotionConfig,
    NcvDiscreteMotion,
    NcvMotion,
    Scenario,
)

if TYPE_CHECKING:
    from activetrack.models.clutter import ClutteredSensor

__all__ = ["build_motion_model", "build_scan_sensors", "build_sensor"]


def build_motion_model(cfg: MotionConfig) -> MotionModel:
    """The motion model object a ``motion:`` block describes."""
    match cfg:
        case NcvMotion():
            return NearlyConstantVelocity(q=cfg.q)
        case NcvDiscreteMotion():
            return NearlyConstantVelocityDiscrete(sigma_x=cfg.sigma_x, sigma_y=cfg.sigma_y)
        case ConstantTurnMotion():
            return ConstantTurn(omega=cfg.omega, q=cfg.q)
        case CircularMotionConfig():
            return CircularMotion(sigma_omega=cfg.sigma_omega, sigma_v=cfg.sigma_v)
        case CircularKnownOmegaMotion():
            return CircularMotionKnownOmega(omega=cfg.omega, sigma_v=cfg.sigma_v)
    raise ValueError(f"motion.model: unknown {cfg.model!r}")


def build_scan_sensors(scenario: Scenario) -> dict[str, tuple[str, ClutteredSensor]]:
    """Every sensor of a multi-target scenario by id, in scenario order: ``(platform id, the
    sensor in clutter)`` with its field of view and the tracker's gate
    (``tracker.tracks.gate_sigmas``), the one table the simulator, tracker, planner and the
    message conversions use."""
    from activetrack.models.clutter import ClutteredSensor  # it imports the scenario package

    gate = scenario.tracker.tracks.gate_sigmas
    return {
        s.id: (p.id, ClutteredSensor.wrap(build_sensor(s), s, gate))
        for p in scenario.platforms
        for s in p.sensors
    }
