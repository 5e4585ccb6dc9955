"""Performance bounds and cost functions (Hernandez 2004, Valverde, Ramdaras et al. 2010).

- ``pcrlb``: PCRLB for linear dynamics, Hernandez eq. 3 with the Monte Carlo measurement
  contribution of eq. 8-9, batched over candidate sensor positions.
- ``tichavsky``: general nonlinear PCRLB (Valverde eq. 56-65).
- ``taylor_crlb``: CRLB without process noise along a nominal path (Valverde eq. 44-51).
- ``mre``: modified Riccati equation with detection probability (Ramdaras eq. 23).
- ``costs``: b_k (Hernandez eq. 10), trace, determinant, position determinant (Ramdaras eq. 24)
  and heading / range / Doppler / bearing variance (Ramdaras eq. 25-26). The planner criteria
  built on them are registered in :mod:`activetrack.planning.criteria`.
"""

from activetrack.bounds.costs import (
    criterion_jacobian,
    criterion_variance,
    determinant_cost,
    position_determinant,
    rmse_bound,
    rmse_bound_of_information,
    trace_cost,
)
from activetrack.bounds.mre import mre_predict, mre_recursion, mre_step, mre_update
from activetrack.bounds.pcrlb import (
    covariance_bound,
    gaussian_samples,
    measurement_information,
    pcrlb_step,
    pcrlb_trajectory,
    propagate_samples,
)
from activetrack.bounds.taylor_crlb import nominal_path, taylor_crlb, taylor_information_initial
from activetrack.bounds.tichavsky import tichavsky_pcrlb, tichavsky_step

__all__ = [
    "covariance_bound",
    "criterion_jacobian",
    "criterion_variance",
    "determinant_cost",
    "gaussian_samples",
    "measurement_information",
    "mre_predict",
    "mre_recursion",
    "mre_step",
    "mre_update",
    "nominal_path",
    "pcrlb_step",
    "pcrlb_trajectory",
    "position_determinant",
    "propagate_samples",
    "rmse_bound",
    "rmse_bound_of_information",
    "taylor_crlb",
    "taylor_information_initial",
    "tichavsky_pcrlb",
    "tichavsky_step",
    "trace_cost",
]
