"""Target motion models (contract: ``activetrack.models.base.MotionModel``), frozen
dataclasses, one small file per family.
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
