"""Several platforms: optimise each in turn given the others' current plans (Hernandez
sec. 4.1), until no plan changes or ``max_iterations`` passes (footnote 4: 10). A platform is
searched again only when another changed its plan since (the search is deterministic).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from activetrack.planning.horizons import HorizonStage, SearchSettings, search_horizon
from activetrack.planning.manoeuvre import PlannerPlatform, hold_course

if TYPE_CHECKING:
    from activetrack.planning.objective import Objective

__all__ = ["Coordination", "PlatformStages", "coordinate_platforms"]

# Plans closer than this (rad, m/s) count as unchanged.
_SAME_PLAN_ATOL = 1e-9


class PlatformStages(Protocol):
    """The search stages of one decision, as the platforms' paths change."""

    def follow(self, i: int, path: np.ndarray) -> None:
        """Platform ``i`` flies ``path`` (its pv at k+1..k+R, ``(R, 4)``) from now on."""
        ...

    def stage(self, j: int) -> HorizonStage:
        """Platform ``j``'s stage, every other platform on the path it follows."""
        ...


@dataclass(frozen=True)
class Coordination:
    """Outcome of the iteration: plans ``[(R, 2)]`` per platform (None if not controllable),
    every platform's path at k+1..k+R ``[(R, 4)]``, cost evaluations, passes, convergence."""

    plans: list[np.ndarray | None]
    paths: list[np.ndarray]
    evaluations: int
    iterations: int
    converged: bool


def coordinate_platforms(
    platforms: Sequence[PlannerPlatform],
    stages: PlatformStages,
    objective: Objective,
    state0: np.ndarray,
    dt: float,
    settings: SearchSettings | None,
    horizon: int,
    max_iterations: int = 10,
    rng: np.random.Generator | None = None,
) -> Coordination:
    """Coordinate-wise optimisation of the controllable platforms' R-leg plans, each by
    :func:`activetrack.planning.horizons.search_horizon` of ``objective`` from ``state0`` with
    ``settings`` (None only when no platform is controllable), starting from "hold course"."""
    R = int(horizon)
    plans: list[np.ndarray | None] = [
        hold_course(p.heading_and_speed[1], p.limits, R) if p.limits else None for p in platforms
    ]
    paths = [p.path(dt, R, plan) for p, plan in zip(platforms, plans, strict=True)]
    for i, path in enumerate(paths):
        stages.follow(i, path)
    controllable = [j for j, plan in enumerate(plans) if plan is not None]
    if not controllable:  # nobody to steer: converged at the first pass
        return Coordination(plans, paths, 0, 1, True)
    if settings is None:
        raise ValueError("settings: a search is required to steer a controllable platform")
    changed_at, clock = [0] * len(platforms), 0
    searched_at: dict[int, int] = {}
    evaluations, iterations, converged = 0, 0, False
    for _ in range(int(max_iterations)):
        iterations += 1
        changed = False
        for j in controllable:
            others = (c for i, c in enumerate(changed_at) if i != j)
            if j in searched_at and all(c <= searched_at[j] for c in others):
                continue
            p = platforms[j]
            best = search_horizon(stages.stage(j), objective, state0, p, dt, settings, R, rng)
            evaluations += best.evaluations
            clock += 1
            searched_at[j] = clock
            current = plans[j]  # hold course or the last plan: never None when controllable
            if current is None or not np.allclose(
                best.plan, current, rtol=0.0, atol=_SAME_PLAN_ATOL
            ):
                plans[j], paths[j] = best.plan, p.path(dt, R, best.plan)
                stages.follow(j, paths[j])
                changed_at[j] = clock
                changed = True
        if not changed:
            converged = True
            break
    return Coordination(plans, paths, evaluations, iterations, converged)
