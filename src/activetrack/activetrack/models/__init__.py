"""Target motion models and sensor measurement models; their contracts in ``models.base``
(docs/core-interfaces.md). A sensor kind reaches scenario files through
``activetrack.scenarios.register_sensor``.
"""

from activetrack.models.base import (
    GaussianSensor,
    Linearization,
    LinearMotionModel,
    MotionModel,
    SensorModel,
    as_linear,
    jacobian_information,
)
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
    "GaussianSensor",
    "LinearMotionModel",
    "Linearization",
    "MotionModel",
    "NearlyConstantVelocity",
    "NearlyConstantVelocityDiscrete",
    "RangeBearingSensor",
    "RangeRateBearingSensor",
    "SensorModel",
    "as_linear",
    "jacobian_information",
    "state_jacobian",
]
