"""Target motion models and sensor measurement models (see docs/core-interfaces.md)."""

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
    state_jacobian,
)

__all__ = [
    "AmbiguousBearingSensor",
    "BearingSensor",
    "CircularMotion",
    "CircularMotionKnownOmega",
    "ConstantTurn",
    "NearlyConstantVelocity",
    "NearlyConstantVelocityDiscrete",
    "RangeBearingSensor",
    "RangeRateBearingSensor",
    "state_jacobian",
]
