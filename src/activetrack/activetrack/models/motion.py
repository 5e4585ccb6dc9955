"""Target motion models (contract: ``activetrack.models.base.MotionModel``).

Every model is a frozen dataclass with ``dim``, ``state_names``, ``propagate(x, dt)``,
``jacobian(x, dt)``, ``process_noise(dt, x=None)``, ``sample(x, dt, rng)``, ``kinematics(x)``,
``kinematics_jacobian(x)``, ``is_linear`` (plus ``transition_matrix(dt)`` when linear, the
``LinearMotionModel`` contract) and ``state_is_pv`` (the state is the pv vector itself).
The implementations live in one small file per family.
"""

from activetrack.models.circular import CircularMotion, CircularMotionKnownOmega
from activetrack.models.ncv import NearlyConstantVelocity, NearlyConstantVelocityDiscrete
from activetrack.models.turn import ConstantTurn

__all__ = [
    "CircularMotion",
    "CircularMotionKnownOmega",
    "ConstantTurn",
    "NearlyConstantVelocity",
    "NearlyConstantVelocityDiscrete",
]
