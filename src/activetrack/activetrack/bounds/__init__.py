"""Performance bounds and cost functions: ``pcrlb`` (Hernandez eq. 3, 8-9), ``tichavsky``
(Valverde eq. 56-65), ``taylor_crlb`` (Valverde eq. 44-51), ``mre`` (Ramdaras eq. 23) and
``costs`` (Hernandez eq. 10, Ramdaras eq. 24-26).
"""

from activetrack.bounds.costs import (
    criterion_jacobian,
    criterion_variance,
    determinant_cost,
    position_determinant,
    position_trace,
    position_trace_of_information,
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
    "position_trace",
    "position_trace_of_information",
    "propagate_samples",
    "rmse_bound",
    "rmse_bound_of_information",
    "taylor_crlb",
    "taylor_information_initial",
    "tichavsky_pcrlb",
    "tichavsky_step",
    "trace_cost",
]
