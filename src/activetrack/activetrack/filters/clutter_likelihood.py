"""The particle filter's likelihood of a whole scan in clutter (the PDA measurement model).

One scan of ``m`` unlabelled detections ``z_1..z_m`` from one sensor; the target, at state
``x``, is detected with probability ``Pd`` when it is inside the scan's field of view and the
sensor's detection ranges (``I(x) = 1``), its detection is ``z = h(x) + v``, ``v ~ N(0, R)``,
and the false alarms are Poisson with density ``lambda`` per unit of z, uniform over the field
of view (Bar-Shalom, Daum & Huang, "The probabilistic data association filter", IEEE Control
Systems Magazine 29(6), 2009, the PDAF's assumptions and measurement likelihood; Niu, Willett
& Bar-Shalom 2001, sec. II, the model of :mod:`activetrack.models.irf`).  Summing over "no
detection is the target's" and "z_j is", and dividing by the clutter-only likelihood, which
does not depend on ``x``::

    p(Z | x)  ∝  (1 - Pd I(x))  +  Pd I(x) sum_j N(z_j; h(x), R) / lambda

over the detections in the track's gate (outside it the Gaussian term is negligible; the gate
is the tracker's).  ``N(z_j; h(x), R)`` is the sensor's own ``log_likelihood``
(contract :class:`activetrack.models.base.SensorModel`: angle residuals wrapped).

Two limits are kept finite on purpose, so that the particle filter and the JPDA-EKF
(:mod:`activetrack.filters.jpda`) can run on any scenario:

- no clutter (``lambda = 0``): the ratio above divides by lambda, so lambda is floored at
  :data:`CLUTTER_FLOOR` (per unit of z).  With it a detection is "surely the target's" unless
  its Gaussian density is below ~1e-12, which is what the clutter-free model says;
- ``Pd = 1``: "this track has no detection" (a target that left or died, two tracks on one
  detection) would have probability 0 and the JPDA has no feasible event, so ``Pd`` is capped
  at :data:`PD_MAX` = 1 - 1e-9.  The betas then differ from the exact ``Pd = 1`` ones by
  ~1e-9 / l, l the likelihood ratio (far below 1e-9 for a gated detection).
"""

from __future__ import annotations

import math

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_in_range, require_nonnegative
from activetrack.models.base import SensorModel
from activetrack.models.fov import FieldOfView

__all__ = [
    "CLUTTER_FLOOR",
    "PD_MAX",
    "effective_clutter_density",
    "effective_pd",
    "scan_log_likelihood",
]

CLUTTER_FLOOR = 1e-12  # per unit of z (rad, or m rad)
PD_MAX = 1.0 - 1e-9


def effective_clutter_density(clutter_density: float) -> float:
    """``max(lambda, CLUTTER_FLOOR)``: the density the likelihood ratios divide by."""
    return max(require_nonnegative("clutter_density", clutter_density), CLUTTER_FLOOR)


def effective_pd(pd: float) -> float:
    """``min(Pd, PD_MAX)``: a detection probability that leaves "no detection" possible."""
    return min(require_in_range("pd", pd, 0.0, 1.0), PD_MAX)


def scan_log_likelihood(
    sensor: SensorModel,
    Z: ArrayLike,
    target_pv: ArrayLike,
    sensor_pv: ArrayLike,
    fov: FieldOfView,
    *,
    pd: float,
    clutter_density: float,
) -> FloatArray:
    """``log p(Z | x)`` up to a constant for every state of ``target_pv`` ``(N, 4)``: ``(N,)``.

    sensor: the clutter-free sensor model (its ``log_likelihood`` and ``in_range``);
    Z: the gated detections ``(m, dim_z)`` (m >= 0); sensor_pv: the platform's pv ``(4,)``;
    fov: where the scan looked; pd, clutter_density: the sensor's, taken through
    :func:`effective_pd` and :func:`effective_clutter_density`.

    ``log[(1 - Pd I) + Pd I sum_j exp(log N_j) / lambda]`` by ``logaddexp`` so a sharp
    likelihood neither overflows nor underflows; 0 where ``I(x) = 0`` (nothing is learnt
    there: the target could not have been seen).
    """
    X = np.asarray(target_pv, dtype=float)
    s = np.asarray(sensor_pv, dtype=float)
    d = int(sensor.dim_z)
    Zm = np.asarray(Z, dtype=float).reshape(-1, d)
    Pd = effective_pd(pd)
    lam = effective_clutter_density(clutter_density)
    inside = np.asarray(fov.contains(X, s), dtype=bool) & np.asarray(sensor.in_range(X, s))
    log_miss = math.log1p(-Pd)
    if Zm.shape[0] == 0:
        return np.where(inside, log_miss, 0.0)
    terms = np.empty((Zm.shape[0], X.shape[0]))
    for j, z in enumerate(Zm):  # a few gated detections; each term vectorised over particles
        ell, log_norm = sensor.log_likelihood(z, X, s)
        terms[j] = ell + log_norm
    log_sum = np.logaddexp.reduce(terms, axis=0)  # log sum_j N(z_j; h(x), R)
    log_detected = math.log(Pd) - math.log(lam) + log_sum
    return np.where(inside, np.logaddexp(log_miss, log_detected), 0.0)
