"""The horizon search: one platform's best R-leg manoeuvre sequence for an objective, the
other platforms' fixed (Hernandez sec. 3.3-4, eq. 11-16; Ramdaras sec. 7). A stage
(:class:`HorizonStage`) says how a candidate changes the state at each leg (e.g. J by Hernandez
eq. 3, :class:`activetrack.planning.costs.HorizonModel`, or P by Ramdaras eq. 23,
:class:`activetrack.planning.selection.MreStage`); the objective
(:class:`activetrack.planning.objective.Objective`) what those states cost.

Searches (:class:`SearchSettings`): lockstep grid, quadrant or sector searches nested one per
leg, the dynamic programme of eq. 13-16 (eq. 11 for one leg), the inner searches of all outer
candidates batched and each J_prev's share (:meth:`HorizonStage.prepare`) done once; or
``"evolution"`` over all R manoeuvres (eq. 16, sec. 3.3.4) seeded with "hold course". Every
candidate state counts as one cost evaluation; only the first of the R legs is flown.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Protocol

import numpy as np

from activetrack.kernels import kernels_enabled, prefer_kernels
from activetrack.planning.manoeuvre import (
    PlannerPlatform,
    PlatformLimits,
    hold_course,
    manoeuvre_to_unit,
    speed_interval,
    step_platform,
    unit_to_manoeuvre,
)
from activetrack.planning.searches import (
    SEARCHES,
    SearchResult,
    check_integer,
    evolution_search,
    grid_search,
    quadrant_search,
    sector_search,
)

if TYPE_CHECKING:
    from activetrack.planning.objective import Objective

__all__ = [
    "HorizonPlan",
    "HorizonStage",
    "SearchSettings",
    "check_horizon",
    "search_horizon",
    "warm_up",
]

# A batched search: (cost_fn, n_problems) -> SearchResult (activetrack.planning.searches).
LockstepSearch = Callable[..., SearchResult]


@dataclass(frozen=True)
class SearchSettings:
    """Which search explores the reachable region and its size parameters."""

    search: str = "quadrant"
    grid_size: int = 101
    quadrant_divisions: int = 6
    quadrant_patience: int | None = None
    sector_levels: int = 3
    evolution_popsize: int = 15
    evolution_maxiter: int = 100
    evolution_tol: float = 1e-6

    def __post_init__(self) -> None:
        if self.search not in SEARCHES:
            raise ValueError(f"search must be one of {SEARCHES}, got {self.search!r}")
        check_integer("grid_size", self.grid_size, 2)
        for name in (
            "quadrant_divisions",
            "sector_levels",
            "evolution_popsize",
            "evolution_maxiter",
        ):
            check_integer(name, getattr(self, name))
        p = self.quadrant_patience
        if p is not None and (isinstance(p, bool) or int(p) != p or p < 1):
            raise ValueError(f"quadrant_patience must be an integer >= 1 or None, got {p!r}")
        if not (np.isfinite(self.evolution_tol) and self.evolution_tol >= 0):
            raise ValueError(f"evolution_tol must be finite and >= 0, got {self.evolution_tol!r}")

    def evaluations_per_platform(self, horizon: int) -> int:
        """Cost evaluations of one platform's R-step optimisation (at most, for the quadrant
        search with patience)."""
        if self.search == "evolution":
            return self.evolution_popsize * 2 * horizon * (self.evolution_maxiter + 1)
        per_stage = {
            "grid": self.grid_size**2,
            "quadrant": 9 + 5 * (self.quadrant_divisions - 1),
            "sector": 16 + 12 * (self.sector_levels - 1) + 1,
        }[self.search]
        return int(per_stage**horizon)

    def lockstep_search(self) -> LockstepSearch:
        """The batched search function ``(cost_fn, n_problems) -> SearchResult``."""
        if self.search == "grid":
            return partial(grid_search, size=self.grid_size)
        if self.search == "quadrant":
            return partial(
                quadrant_search,
                divisions=self.quadrant_divisions,
                patience=self.quadrant_patience,
            )
        if self.search == "sector":
            return partial(sector_search, levels=self.sector_levels)
        raise ValueError(f"search {self.search!r} has no lockstep form")


class HorizonStage(Protocol):
    """How one platform's candidate manoeuvres change a state (J or P of every track, trailing
    axes ``(T, 4, 4)``) leg by leg; ``state0`` at epoch k is shared by every candidate."""

    def prepare(self, state: np.ndarray, level: int) -> np.ndarray:
        """What leg ``level`` starts from, computed once for all its candidates: from
        ``state0`` (level 0) or the states ``(B, ...)`` of B problems, leading axes kept (e.g.
        the prediction part of Hernandez eq. 3, which depends on J_prev only)."""
        ...

    def advance(self, prepared: np.ndarray, level: int, pv: np.ndarray) -> np.ndarray:
        """The states after leg ``level`` (epoch k+1+level) from ``prepared`` (as returned at
        level 0, else ``(b, 1, ...)``) with the platform at pv ``(b, C, 4)``: ``(b, C, ...)``."""
        ...


@dataclass(frozen=True)
class HorizonPlan:
    """The best manoeuvre sequence ``(R, 2)`` of (dpsi, v'), its objective and the cost
    evaluations spent (every candidate state of every leg)."""

    plan: np.ndarray
    objective: float
    evaluations: int


def check_horizon(horizon: int) -> int:
    """``horizon`` R as an int if it is an integer >= 1, else ValueError."""
    if isinstance(horizon, bool) or not isinstance(horizon, int | np.integer) or horizon < 1:
        raise ValueError(f"horizon must be an integer >= 1, got {horizon!r}")
    return int(horizon)


def search_horizon(
    stage: HorizonStage,
    objective: Objective,
    state0: np.ndarray,
    platform: PlannerPlatform,
    dt: float,
    settings: SearchSettings,
    horizon: int,
    rng: np.random.Generator | None = None,
) -> HorizonPlan:
    """The controllable ``platform``'s best R-leg manoeuvre sequence: the ``objective`` of the
    states ``stage`` advances from ``state0`` (eq. 11 for R = 1, eq. 15 for R = 2, eq. 16 in
    general), by ``settings``' search (module docstring); ``rng`` seeds the evolution."""
    R = check_horizon(horizon)
    if platform.limits is None:
        raise ValueError(f"platform {platform.platform_id!r} must be controllable (have limits)")
    if settings.search == "evolution":
        return _evolve(stage, objective, state0, platform, platform.limits, dt, settings, R, rng)
    nested = _Nested(stage, objective, platform.limits, dt, settings.lockstep_search(), R)
    heading, speed = platform.heading_and_speed
    plan, value = nested.best(0, state0, platform.pv[None], np.array([heading]), np.array([speed]))
    return HorizonPlan(plan[0], float(value[0]), nested.evaluations)


class _Nested:
    """The lockstep searches nested one per leg (Hernandez eq. 13-16)."""

    def __init__(
        self,
        stage: HorizonStage,
        objective: Objective,
        limits: PlatformLimits,
        dt: float,
        search: LockstepSearch,
        horizon: int,
    ):
        self.stage, self.objective, self.search = stage, objective, search
        self.limits, self.dt, self.horizon = limits, dt, horizon
        self.evaluations = 0

    def best(
        self,
        level: int,
        state: np.ndarray,
        pv: np.ndarray,
        heading: np.ndarray,
        speed: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Best manoeuvres for legs ``level``..R-1 of B problems and their objectives: plans
        ``(B, R - level, 2)``, values ``(B,)``. pv ``(B, 4)``, heading and speed ``(B,)`` at
        epoch k+level; ``state`` is ``state0`` at level 0, else ``(B, ...)``."""
        R, stage = self.horizon, self.stage
        prepared = stage.prepare(state, level)
        legs = _candidate_legs(pv, heading, speed, self.limits, self.dt)

        def cost_fn(rows: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            man, pv1, h1 = legs(rows, u)  # (b, C, 2), (b, C, 4), (b, C)
            b, C = man.shape[:2]
            S1 = stage.advance(prepared if level == 0 else prepared[rows][:, None], level, pv1)
            self.evaluations += b * C
            costs = self.objective.leg_cost(S1, level, R)
            plan = man[:, :, None, :]
            if level + 1 == R:
                return (np.zeros((b, C)) if costs is None else costs), plan
            if S1.shape[:2] != (b, C):  # a state that no candidate changes
                S1 = np.broadcast_to(S1, (b, C, *S1.shape[2:]))
            tail, value = self.best(
                level + 1,
                S1.reshape(b * C, *S1.shape[2:]),
                pv1.reshape(-1, 4),
                h1.reshape(-1),
                man[..., 1].reshape(-1),
            )
            value = value.reshape(b, C)
            costs = value if costs is None else costs + value
            return costs, np.concatenate([plan, tail.reshape(b, C, R - level - 1, 2)], axis=2)

        result = self.search(cost_fn, len(speed))
        return result.payload(), result.cost


# (rows (b,), u (b, C, 2)) -> manoeuvres (b, C, 2), pv (b, C, 4), headings (b, C)
Legs = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


def _candidate_legs(
    pv: np.ndarray, heading: np.ndarray, speed: np.ndarray, limits: PlatformLimits, dt: float
) -> Legs:
    """(rows, u) -> manoeuvres, pv and headings at the next epoch of the candidates u
    ``(b, C, 2)`` of problems ``rows``: unit_to_manoeuvre then step_platform, compiled in one
    call (``planning._kernels.candidate_legs``, the same operations) where the kernels are on."""
    if not kernels_enabled():

        def numpy_legs(
            rows: np.ndarray, u: np.ndarray
        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            man = unit_to_manoeuvre(u, speed[rows, None], limits)
            pv1, h1 = step_platform(pv[rows, None, :], heading[rows, None], man, dt)
            return man, pv1, h1

        return numpy_legs
    from activetrack.planning._kernels import candidate_legs

    v_lo, v_hi = speed_interval(speed, limits)
    return lambda rows, u: candidate_legs(u, rows, pv, heading, v_lo, v_hi, limits.dpsi_max, dt)


def _evolve(
    stage: HorizonStage,
    objective: Objective,
    state0: np.ndarray,
    platform: PlannerPlatform,
    limits: PlatformLimits,
    dt: float,
    settings: SearchSettings,
    R: int,
    rng: np.random.Generator | None,
) -> HorizonPlan:
    """All R manoeuvres at once by differential evolution (Hernandez eq. 16, sec. 3.3.4)."""
    heading, speed = platform.heading_and_speed
    evaluations = 0

    def cost_fn(rows: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        nonlocal evaluations
        u = u[0].reshape(-1, R, 2)  # (n, R, 2): the population
        n = u.shape[0]
        p, h = np.broadcast_to(platform.pv, (1, n, 4)), np.full((1, n), heading)
        v = np.full(n, speed)
        state, total, plan = state0, np.zeros((1, n)), np.empty((1, n, R, 2))
        for r in range(R):
            plan[0, :, r] = unit_to_manoeuvre(u[:, r], v, limits)
            p, h = step_platform(p, h, plan[:, :, r], dt)
            v = plan[0, :, r, 1]
            state = stage.advance(stage.prepare(state, r), r, p)
            costs = objective.leg_cost(state, r, R)
            if costs is not None:
                total = total + costs
        evaluations += n * R
        return total, plan

    hold = hold_course(speed, limits, R)
    x0 = manoeuvre_to_unit(hold, np.concatenate([[speed], hold[:-1, 1]]), limits).reshape(-1)
    result = evolution_search(
        cost_fn,
        2 * R,
        rng,
        popsize=settings.evolution_popsize,
        maxiter=settings.evolution_maxiter,
        tol=settings.evolution_tol,
        x0=x0,
    )
    return HorizonPlan(result.payload()[0], float(result.cost[0]), evaluations)


def warm_up() -> None:
    """Compile (or load) ``planning._kernels`` with the argument types the planner passes."""
    from activetrack.planning._kernels import candidate_legs

    def cost_fn(rows: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return u[..., 0] + u[..., 1], u.copy()

    with prefer_kernels():  # the compiled bookkeeping, whatever the mode
        quadrant_search(cost_fn, 2, divisions=2)
        quadrant_search(lambda rows, u: u[..., 0] * u[..., 1], 1, divisions=2)
    rows, one = np.zeros(1, dtype=np.int64), np.ones(1)
    candidate_legs(np.full((1, 1, 2), 0.5), rows, np.zeros((1, 4)), one, one, one, 0.1, 1.0)
