"""The two limits of the clutter model that the JPDA keeps finite on purpose, so that every
filter can track in any scene. The likelihood ratio of "z_j is the target's" against clutter is
``Pd N(z_j; zhat, S) / lambda`` (:mod:`activetrack.filters.jpda`), with false alarms Poisson of
density ``lambda`` per unit of z:

- no clutter (``lambda = 0``): the ratio divides by lambda, so lambda is floored at
  :data:`CLUTTER_FLOOR` (per unit of z). With it a detection is "surely the target's" unless
  its Gaussian density is below ~1e-12, which is what the clutter-free model says;
- ``Pd = 1``: "this track has no detection" (a target that left or died, two tracks on one
  detection) would have probability 0 and the JPDA has no feasible event, so ``Pd`` is capped
  at :data:`PD_MAX` = 1 - 1e-9. The betas then differ from the exact ``Pd = 1`` ones by
  ~1e-9 / l, l the likelihood ratio (far below 1e-9 for a gated detection).
"""

from __future__ import annotations

from activetrack.checks import require_in_range, require_nonnegative

__all__ = ["CLUTTER_FLOOR", "PD_MAX", "effective_clutter_density", "effective_pd"]

CLUTTER_FLOOR = 1e-12  # per unit of z (rad, or m rad)
PD_MAX = 1.0 - 1e-9


def effective_clutter_density(clutter_density: float) -> float:
    """``max(lambda, CLUTTER_FLOOR)``: the density the likelihood ratios divide by."""
    return max(require_nonnegative("clutter_density", clutter_density), CLUTTER_FLOOR)


def effective_pd(pd: float) -> float:
    """``min(Pd, PD_MAX)``: a detection probability that leaves "no detection" possible."""
    return min(require_in_range("pd", pd, 0.0, 1.0), PD_MAX)
