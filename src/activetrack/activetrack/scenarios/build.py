"""Build core objects (motion models, sensors) from validated scenario configuration."""

from __future__ import annotations

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
from activetrack.scenarios.schema import MotionConfig, SensorConfig


def build_motion_model(cfg: MotionConfig):
    """The motion model object a ``motion:`` block describes."""
    match cfg.model:
        case "ncv":
            return NearlyConstantVelocity(q=cfg.q)
        case "ncv_discrete":
            return NearlyConstantVelocityDiscrete(sigma_x=cfg.sigma_x, sigma_y=cfg.sigma_y)
        case "constant_turn":
            return ConstantTurn(omega=cfg.omega, q=cfg.q)
        case "circular":
            return CircularMotion(sigma_omega=cfg.sigma_omega, sigma_v=cfg.sigma_v)
        case "circular_known_omega":
            return CircularMotionKnownOmega(omega=cfg.omega, sigma_v=cfg.sigma_v)
    raise ValueError(f"motion.model: unknown {cfg.model!r}")


def build_sensor(cfg: SensorConfig):
    """The sensor object a ``sensors:`` entry describes."""
    common = {"pd": cfg.pd, "r_min": cfg.r_min, "r_max": cfg.r_max}
    match cfg.kind:
        case "bearing":
            return BearingSensor(sigma=cfg.sigma, **common)
        case "ambiguous_bearing":
            return AmbiguousBearingSensor(sigma=cfg.sigma, **common)
        case "range_bearing":
            return RangeBearingSensor(sigma_r=cfg.sigma_r, sigma_b=cfg.sigma_b, **common)
        case "range_rate_bearing":
            return RangeRateBearingSensor(
                sigma_r=cfg.sigma_r, sigma_rr=cfg.sigma_rr, sigma_b=cfg.sigma_b, **common
            )
    raise ValueError(f"sensors.kind: unknown {cfg.kind!r}")
