"""Target motion models and sensor measurement models (see docs/core-interfaces.md).

The contracts are :class:`MotionModel` / :class:`LinearMotionModel` and :class:`SensorModel`
(``activetrack.models.base``); :class:`GaussianSensor` is the base class that gives a new sensor
generic versions of everything but its h(x), Jacobian and R. A sensor kind is made available to
scenario files by ``activetrack.scenarios.register_sensor``.
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
