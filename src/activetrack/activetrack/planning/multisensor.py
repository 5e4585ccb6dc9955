"""Several platforms: optimise each in turn given the others' current plans (Hernandez
sec. 4.1), until no plan changes or ``max_iterations`` passes (footnote 4: 10). A platform is
searched again only when another it interacts with changed its plan since (the search is
deterministic).

Platforms whose sensors serve disjoint sets of tracks (``supports``) do not interact when the
objective is a sum of per-track costs: another platform's plan then adds the same constant to
every candidate of this one, so its best plan stays where it was and it is not searched again.
The problem separates into the connected components of "serve a common track", each solved by
the same iteration on its own; the joint optimum is the product of theirs (additive costs,
disjoint supports). The plans are those of searching every platform again, unless two of a
platform's candidates tie to within the round-off of that constant.
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

__all__ = ["Coordination", "PlatformStages", "coordinate_platforms", "interactions"]

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
    supports: Sequence[np.ndarray | None] | None = None,
) -> Coordination:
    """Coordinate-wise optimisation of the controllable platforms' R-leg plans, each by
    :func:`activetrack.planning.horizons.search_horizon` of ``objective`` from ``state0`` with
    ``settings`` (None only when no platform is controllable), starting from "hold course".
    ``supports``: per platform, the tracks ``(T,)`` bool its candidates change (None: every
    state, so it interacts with every platform); give them only for an objective that sums
    per-track costs and a deterministic search (module docstring). None: all interact."""
    R = int(horizon)
    interacts = interactions(supports, len(platforms))
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
            others = (c for i, c in enumerate(changed_at) if i != j and interacts[i, j])
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


def interactions(supports: Sequence[np.ndarray | None] | None, n_platforms: int) -> np.ndarray:
    """``(P, P)`` bool: whether two platforms' ``supports`` (the tracks each changes, ``(T,)``
    bool; None: all) share a track (a platform with itself: True); every pair when
    ``supports`` is None."""
    if supports is None:
        return np.ones((n_platforms, n_platforms), dtype=bool)
    if len(supports) != n_platforms:
        raise ValueError(
            f"supports must hold one entry per platform ({n_platforms}), got {len(supports)}"
        )
    every = [s is None for s in supports]
    masks = [np.asarray(s, dtype=bool) for s in supports if s is not None]
    if len({m.shape for m in masks}) > 1 or any(m.ndim != 1 for m in masks):
        raise ValueError("supports must be (T,) bool arrays of one length T")
    out = np.ones((n_platforms, n_platforms), dtype=bool)
    for i, si in enumerate(supports):
        for j, sj in enumerate(supports):
            if i != j and not (every[i] or every[j]):
                out[i, j] = bool(np.any(np.asarray(si, dtype=bool) & np.asarray(sj, dtype=bool)))
    return out
