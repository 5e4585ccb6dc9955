"""Planning horizons for one platform (the others' manoeuvres fixed).

- Single step (Hernandez eq. 11): a_k = argmin b_{k+1}.
- Two-step dynamic programming (eq. 13-15): for each candidate a_k the inner search finds
  a_{k+1} | a_k minimising b_{k+2} (eq. 13-14), and a_k minimises b_{k+1} + b_{k+2}(a_k) (eq. 15).
  The same recursion nests for any R (eq. 16), with the inner searches of all outer candidates
  of a stage run in lockstep (one batched PCRLB call per stage and level).
- R-step by evolution (eq. 16, sec. 3.3.4): differential evolution over all R manoeuvres.

Manoeuvres are returned physically, ``(R, 2)`` rows of (dpsi, v'); only the first is flown
(receding horizon), the rest is the plan the objective assumed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from activetrack.kernels import kernels_enabled
from activetrack.planning.costs import HorizonModel
from activetrack.planning.manoeuvre import (
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
    evolution_search,
    grid_search,
    quadrant_search,
    sector_search,
)

__all__ = ["SearchSettings", "optimise_platform"]

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
        for name, lo in (
            ("grid_size", 2),
            ("quadrant_divisions", 1),
            ("sector_levels", 1),
            ("evolution_popsize", 1),
            ("evolution_maxiter", 1),
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < lo:
                raise ValueError(f"{name} must be an integer >= {lo}, got {value!r}")
        p = self.quadrant_patience
        if p is not None and (isinstance(p, bool) or int(p) != p or p < 1):
            raise ValueError(f"quadrant_patience must be an integer >= 1 or None, got {p!r}")
        if not (np.isfinite(self.evolution_tol) and self.evolution_tol >= 0):
            raise ValueError(f"evolution_tol must be finite and >= 0, got {self.evolution_tol!r}")

    def evaluations_per_platform(self, horizon: int) -> int:
        """Cost evaluations of one platform's R-step optimisation (at most, for the quadrant
        search with patience): per_stage^R for the nested lockstep searches, the population
        over all generations for evolution."""
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


def _dynamic_programme(
    model: HorizonModel,
    level: int,
    J_prev: np.ndarray,
    pv: np.ndarray,
    heading: np.ndarray,
    speed: np.ndarray,
    limits: PlatformLimits,
    dt: float,
    search: LockstepSearch,
) -> tuple[np.ndarray, np.ndarray]:
    """Best manoeuvres for epochs k+level..k+R-1 of B problems, and their summed cost.

    J_prev ``(B, 4, 4)``, pv ``(B, 4)``, heading and speed ``(B,)`` at epoch k+level.
    Returns the plans ``(B, R - level, 2)`` and the values ``(B,)`` (eq. 13-15 nested).
    """
    R = model.horizon
    J_pred = model.predict(J_prev)  # (B, 4, 4): the same for every stage of the search
    legs = _candidate_legs(pv, heading, speed, limits, dt)

    def cost_fn(rows: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        man, pv1, h1 = legs(rows, u)  # (b, C, 2), (b, C, 4), (b, C)
        J1 = model.update(J_pred[rows, None], level, pv1)  # (b, C, 4, 4)
        costs = model.cost(J1)
        plan = man[:, :, None, :]
        if level + 1 < R:
            b, C = costs.shape
            tail, value = _dynamic_programme(
                model,
                level + 1,
                J1.reshape(-1, 4, 4),
                pv1.reshape(-1, 4),
                h1.reshape(-1),
                man[..., 1].reshape(-1),
                limits,
                dt,
                search,
            )
            costs = costs + value.reshape(b, C)
            plan = np.concatenate([plan, tail.reshape(b, C, R - level - 1, 2)], axis=2)
        return costs, plan

    result = search(cost_fn, len(speed))
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


def _evolution(
    model: HorizonModel,
    J0: np.ndarray,
    pv: np.ndarray,
    heading: float,
    speed: float,
    limits: PlatformLimits,
    dt: float,
    settings: SearchSettings,
    rng: np.random.Generator | None,
) -> tuple[np.ndarray, float]:
    """All R manoeuvres at once by differential evolution (eq. 16)."""
    R = model.horizon

    def cost_fn(rows: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u = u[0].reshape(-1, R, 2)  # (P, R, 2)
        P = u.shape[0]
        p, h, v = np.broadcast_to(pv, (P, 4)), np.full(P, heading), np.full(P, speed)
        J, total, plan = J0, np.zeros(P), np.empty((P, R, 2))
        for r in range(R):
            plan[:, r] = unit_to_manoeuvre(u[:, r], v, limits)
            p, h = step_platform(p, h, plan[:, r], dt)
            v = plan[:, r, 1]
            J = model.step(J, r, p)
            total += model.cost(J)
        return total[None], plan[None]

    # Seed the population with "hold course" so the search starts from a feasible default.
    hold = hold_course(speed, limits, R)
    speeds = np.concatenate([[speed], hold[:-1, 1]])
    x0 = manoeuvre_to_unit(hold, speeds, limits).reshape(-1)
    result = evolution_search(
        cost_fn,
        2 * R,
        rng,
        popsize=settings.evolution_popsize,
        maxiter=settings.evolution_maxiter,
        tol=settings.evolution_tol,
        x0=x0,
    )
    return result.payload()[0], float(result.cost[0])


def optimise_platform(
    model: HorizonModel,
    J0: np.ndarray,
    pv: np.ndarray,
    heading: float,
    speed: float,
    limits: PlatformLimits,
    dt: float,
    settings: SearchSettings,
    rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, float]:
    """Best R-step manoeuvre plan ``(R, 2)`` of (dpsi, v') for one platform and its objective
    sum_{r=1..R} cost(J_{k+r}) (eq. 11 for R = 1, eq. 15 for R = 2, eq. 16 in general).

    J0: information at epoch k ``(4, 4)``; pv, heading, speed: the platform at epoch k.
    ``settings.search == "evolution"`` uses differential evolution, any other search the
    (nested) dynamic programme.
    """
    if settings.search == "evolution":
        return _evolution(model, J0, pv, heading, speed, limits, dt, settings, rng)
    plan, value = _dynamic_programme(
        model,
        0,
        np.asarray(J0, dtype=float)[None],
        np.asarray(pv, dtype=float)[None],
        np.array([heading], dtype=float),
        np.array([speed], dtype=float),
        limits,
        dt,
        settings.lockstep_search(),
    )
    return plan[0], float(value[0])
