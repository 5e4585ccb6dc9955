"""Several platforms: optimise each in turn given the others' current plans (Hernandez
sec. 4.1), until no platform changes its plan or ``max_iterations`` passes (footnote 4: 10).

Each platform's plan covers the whole horizon; while platform j is optimised the others fly
their current plans (their second-step manoeuvres included), so with two-step planning only the
platform being optimised re-plans its second step. Platforms without limits are not
controllable and hold course.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from activetrack.arraytypes import ArrayLike
from activetrack.bounds.pcrlb import pcrlb_step
from activetrack.planning.costs import (
    HorizonModel,
    InformationCache,
    criterion_cost,
    platform_information,
)
from activetrack.planning.horizons import SearchSettings, optimise_platform
from activetrack.planning.manoeuvre import hold_course, rollout

if TYPE_CHECKING:
    from activetrack.planning.planner import PlannerPlatform

__all__ = ["Coordination", "coordinate_platforms", "horizon_information"]

# Plans closer than this (rad, m/s) count as unchanged.
_SAME_PLAN_ATOL = 1e-9


@dataclass(frozen=True)
class Coordination:
    """Outcome of the iteration: plans ``[(R, 2)]`` per platform (None if not controllable),
    the horizon objective with everybody's plans, J at k+1..k+R ``(R, 4, 4)``, cost
    evaluations, passes, convergence."""

    plans: list[np.ndarray | None]
    objective: float
    J: np.ndarray
    evaluations: int
    iterations: int
    converged: bool


def horizon_information(
    J0: np.ndarray, F: np.ndarray, Q: np.ndarray, contributions: ArrayLike
) -> np.ndarray:
    """J at epochs k+1..k+R from J0 and the summed J_Z of each epoch ``(R, 4, 4)`` (eq. 3)."""
    out, J = [], np.asarray(J0, dtype=float)
    for J_Z in np.asarray(contributions, dtype=float):
        J = pcrlb_step(J, F, Q, J_Z)
        out.append(J)
    return np.stack(out)


def coordinate_platforms(
    platforms: Sequence[PlannerPlatform],
    J0: np.ndarray,
    samples: np.ndarray,
    F: np.ndarray,
    Q: np.ndarray,
    dt: float,
    criterion: str,
    settings: SearchSettings,
    max_iterations: int = 10,
    rng: np.random.Generator | None = None,
) -> Coordination:
    """Coordinate-wise optimisation of the platforms' R-step plans.

    platforms: objects with ``pv`` (4,), ``heading``, ``speed``, ``limits`` (None: not
    controllable) and ``sensors``. samples: target samples at k+1..k+R ``(R, M, 4)``.
    """
    R = samples.shape[0]
    n = len(platforms)
    plans: list[np.ndarray | None] = [
        hold_course(p.heading_and_speed[1], p.limits, R) if p.limits else None for p in platforms
    ]

    def info_of(i: int) -> np.ndarray:
        p, plan_i = platforms[i], plans[i]
        if plan_i is None:  # not controllable: constant velocity legs
            path = p.pv + np.outer(np.arange(1, R + 1) * dt, [p.pv[1], 0.0, p.pv[3], 0.0])
        else:
            path, _ = rollout(p.pv, p.heading_and_speed[0], plan_i, dt)
        return np.stack([platform_information(p.sensors, path[r], samples[r]) for r in range(R)])

    info = [info_of(i) for i in range(n)]
    controllable = [(i, p.limits) for i, p in enumerate(platforms) if p.limits is not None]
    # Each platform's own J_Z of candidate batches, kept across its optimisations in this
    # decision (HorizonModel's cache): a later pass often scores the same candidates again. A
    # single controllable platform is optimised once: nothing to share.
    caches = [InformationCache() if len(controllable) > 1 else None for _ in range(n)]
    # Bookkeeping to skip re-optimising a platform when nobody else changed since its last
    # optimisation (a deterministic search would return the same plan).
    clock, changed_at = 0, [0] * n
    optimised_at: list[int | None] = [None] * n
    evaluations, iterations, converged = 0, 0, False
    for _ in range(int(max_iterations)):
        iterations += 1
        any_change = False
        for j, limits in controllable:
            last = optimised_at[j]
            if last is not None and all(changed_at[i] <= last for i in range(n) if i != j):
                continue
            fixed = sum(info[i] for i in range(n) if i != j) if n > 1 else np.zeros_like(info[j])
            p = platforms[j]
            heading, speed = p.heading_and_speed
            model = HorizonModel(F, Q, samples, fixed, p.sensors, criterion, cache=caches[j])
            plan, _ = optimise_platform(model, J0, p.pv, heading, speed, limits, dt, settings, rng)
            evaluations += model.evaluations
            clock += 1
            optimised_at[j] = clock
            current = plans[j]  # hold course or the last plan: never None when controllable
            if current is None or not np.allclose(plan, current, rtol=0.0, atol=_SAME_PLAN_ATOL):
                plans[j] = plan
                info[j] = info_of(j)
                changed_at[j] = clock
                any_change = True
        if not any_change:
            converged = True
            break
    J = horizon_information(J0, F, Q, sum(info))
    objective = float(np.sum(criterion_cost(criterion, J)))
    return Coordination(plans, objective, J, evaluations, iterations, converged)
