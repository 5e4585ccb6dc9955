"""Searches over the reachable region (the unit square of ``manoeuvre.unit_to_manoeuvre``).

Every search minimises B independent problems in lockstep (so a dynamic programme runs the
inner searches of all outer candidates together) with ``cost_fn(rows, u) -> costs`` or
``(costs, aux)``: ``rows`` ``(b,)`` the problems still searching, ``u`` ``(b, C, 2)`` one
stage's candidates, ``costs`` ``(b, C)``, ``aux`` ``(b, C, ...)`` a payload returned with each
problem's best point.

- :func:`grid_search`: n x n grid (Hernandez sec. 4.2, 101 x 101).
- :func:`quadrant_search`: Hernandez sec. 4.1: split into 4 quadrants by 9 points, split the
  one with the lowest mean corner cost again (5 new points), ``divisions`` times or until
  ``patience`` splits without improvement (6 divisions: at most 34 evaluations).
- :func:`sector_search`: Ramdaras sec. 4: nine sectors (16 corners), split the one with the
  smallest summed corner cost (12 new corners) ``levels`` times, answer its centre.
- :func:`evolution_search`: scipy's differential evolution over the unit cube (Hernandez eq.
  16, sec. 3.3.4); one problem, population vectorised.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from activetrack.kernels import kernels_enabled

__all__ = [
    "SEARCHES",
    "SearchResult",
    "check_integer",
    "evolution_search",
    "grid_search",
    "quadrant_search",
    "sector_search",
]


# cost_fn(rows (b,), u (b, C, D)) -> costs (b, C), or (costs, aux (b, C, ...)).
CostFn = Callable[[np.ndarray, np.ndarray], np.ndarray | tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class SearchResult:
    """Best point per problem: ``u`` ``(B, D)``, ``cost`` ``(B,)``, ``aux`` ``(B, ...)`` or None,
    and ``evaluations``: cost evaluations spent, summed over the B problems."""

    u: np.ndarray
    cost: np.ndarray
    aux: np.ndarray | None
    evaluations: int

    def payload(self) -> np.ndarray:
        """``aux``, for a cost function that returns one (else ValueError)."""
        if self.aux is None:
            raise ValueError("the cost function returned no payload (aux)")
        return self.aux


def _call(cost_fn: CostFn, rows: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    out = cost_fn(rows, u)
    costs, aux = out if isinstance(out, tuple) else (out, None)
    costs = np.asarray(costs, dtype=float)
    if costs.shape != u.shape[:2]:
        raise ValueError(f"cost_fn must return costs of shape {u.shape[:2]}, got {costs.shape}")
    return costs, aux


class _Best:
    """Best point, cost and payload seen so far for each of B problems."""

    def __init__(self, n_problems: int, dim: int = 2):
        self.u = np.full((n_problems, dim), np.nan)
        self.cost = np.full(n_problems, np.inf)
        self.aux: np.ndarray | None = None

    def offer(
        self, rows: np.ndarray, u: np.ndarray, costs: np.ndarray, aux: np.ndarray | None
    ) -> np.ndarray:
        """Take each row's lowest candidate if it beats the stored one; returns improved (b,)."""
        i = np.argmin(costs, axis=1)
        c = costs[np.arange(len(rows)), i]
        better = c < self.cost[rows]
        take = rows[better]
        self.cost[take] = c[better]
        self.u[take] = u[better, i[better]]
        if aux is not None:
            if self.aux is None:
                self.aux = np.zeros((self.cost.shape[0], *aux.shape[2:]))
            self.aux[take] = aux[better, i[better]]
        return better

    def result(self, evaluations: int) -> SearchResult:
        return SearchResult(self.u, self.cost, self.aux, int(evaluations))


def check_integer(name: str, value: int, lo: int = 1) -> int:
    """``value`` as an int if it is an integer >= ``lo`` (not a bool), else ValueError."""
    if isinstance(value, bool) or int(value) != value or value < lo:
        raise ValueError(f"{name} must be an integer >= {lo}, got {value!r}")
    return int(value)


def grid_search(
    cost_fn: CostFn, n_problems: int = 1, size: int = 101, chunk: int = 2048
) -> SearchResult:
    """Enumerative search on a ``size`` x ``size`` grid over the unit square (Hernandez
    sec. 4.2), evaluated in chunks of at most ``chunk`` points per problem per call."""
    B, size = check_integer("n_problems", n_problems), check_integer("size", size, 2)
    if int(chunk) < 1:
        raise ValueError(f"chunk must be >= 1, got {chunk!r}")
    g = np.linspace(0.0, 1.0, size)
    pts = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    rows = np.arange(B)
    best = _Best(B)
    for start in range(0, len(pts), int(chunk)):
        u = np.broadcast_to(pts[start : start + int(chunk)], (B, *pts[start : start + chunk].shape))
        costs, aux = _call(cost_fn, rows, np.array(u))
        best.offer(rows, u, costs, aux)
    return best.result(B * len(pts))


# The 3 x 3 grid entries a division scores: all nine at the first, then the five that are new in
# the chosen quadrant (its corners are inherited), in row-major order as the costs are stored.
_QUADRANT_ALL = np.stack(np.meshgrid(np.arange(3), np.arange(3), indexing="ij"), -1).reshape(9, 2)
_QUADRANT_NEW = _QUADRANT_ALL[[1, 3, 4, 5, 7]]
# A square's corner offsets (a chosen quadrant's or sector's corners become the new square's).
_CORNERS = ((0, 0), (0, 1), (1, 0), (1, 1))


def quadrant_search(
    cost_fn: CostFn, n_problems: int = 1, divisions: int = 6, patience: int | None = None
) -> SearchResult:
    """Hernandez's efficient search (sec. 4.1, Fig. 1), B problems in lockstep; the bookkeeping
    is compiled (``planning._kernels``) when kernels are enabled, with the same decisions."""
    B, divisions = check_integer("n_problems", n_problems), check_integer("divisions", divisions)
    patience = check_integer("patience", divisions if patience is None else patience)
    if not kernels_enabled():
        return _quadrant_search_numpy(cost_fn, B, divisions, patience)
    from activetrack.planning._kernels import quadrant_accept, quadrant_points

    origin, side = np.zeros((B, 2)), np.ones(B)
    values = np.full((B, 3, 3), np.nan)  # costs of the 3 x 3 points of each square
    stale = np.zeros(B, dtype=np.int64)  # divisions without improvement
    best = (np.full((B, 2), np.nan), np.full(B, np.inf), np.zeros((B, 0)))
    state = (values, np.zeros((B, 9, 0)), origin, side, stale)
    rows = np.arange(B, dtype=np.int64)
    aux_shape: tuple[int, ...] | None = None
    evaluations = 0
    for division in range(divisions):
        new = _QUADRANT_ALL if division == 0 else _QUADRANT_NEW
        u = quadrant_points(origin, side, rows, new)
        costs, aux = _call(cost_fn, rows, u)
        evaluations += costs.size
        b, C = costs.shape
        if aux is not None and aux_shape is None:  # the payload's size, from the first call
            aux_shape = aux.shape[2:]
            P = int(np.prod(aux_shape, dtype=int))
            best = (best[0], best[1], np.zeros((B, P)))
            state = (values, np.zeros((B, 9, P)), origin, side, stale)
        flat = np.zeros((b, C, 0)) if aux is None else np.asarray(aux, float).reshape(b, C, -1)
        last = division == divisions - 1
        rows = quadrant_accept(*state, *best, rows, new, u, costs, flat, last, patience)
        if rows.size == 0:
            break
    payload = None if aux_shape is None else best[2].reshape(B, *aux_shape)
    return SearchResult(best[0], best[1], payload, evaluations)


def _quadrant_search_numpy(cost_fn: CostFn, B: int, divisions: int, patience: int) -> SearchResult:
    """:func:`quadrant_search` with numpy bookkeeping (the reference of the compiled one)."""
    offsets = np.array([0.0, 0.5, 1.0])
    ij = np.stack(np.meshgrid(np.arange(3), np.arange(3), indexing="ij"), -1).reshape(9, 2)
    origin = np.zeros((B, 2))
    side = np.ones(B)
    values = np.full((B, 3, 3), np.nan)  # costs of the 3 x 3 points of each square
    payload: np.ndarray | None = None
    stale = np.zeros(B, dtype=int)  # divisions without improvement
    best = _Best(B)
    rows = np.arange(B)
    evaluations = 0
    for division in range(int(divisions)):
        # New points: all 9 at the first division, else the 5 not inherited from the parent.
        new = ij if division == 0 else ij[np.isnan(values[rows[0]]).reshape(-1)]
        u = origin[rows, None, :] + side[rows, None, None] * offsets[new]
        costs, aux = _call(cost_fn, rows, u)
        evaluations += costs.size
        values[rows[:, None], new[:, 0], new[:, 1]] = costs
        if aux is not None:
            if payload is None:
                payload = np.zeros((B, 3, 3, *aux.shape[2:]))
            payload[rows[:, None], new[:, 0], new[:, 1]] = aux
        improved = best.offer(rows, u, costs, aux)
        stale[rows] = np.where(improved, 0, stale[rows] + 1)
        if division == int(divisions) - 1:
            break
        rows = rows[stale[rows] < patience]
        if rows.size == 0:
            break
        # Average corner cost of each quadrant (a, b) in {0, 1}^2; take the lowest.
        v = values[rows]
        quad = 0.25 * (v[:, :2, :2] + v[:, 1:, :2] + v[:, :2, 1:] + v[:, 1:, 1:])
        q = np.argmin(quad.reshape(len(rows), 4), axis=1)
        a, b = q // 2, q % 2
        child = np.full((len(rows), 3, 3), np.nan)
        for da, db in _CORNERS:
            child[:, 2 * da, 2 * db] = v[np.arange(len(rows)), a + da, b + db]
        if payload is not None:
            pchild = np.zeros((len(rows), 3, 3, *payload.shape[3:]))
            for da, db in _CORNERS:
                pchild[:, 2 * da, 2 * db] = payload[rows, a + da, b + db]
            payload[rows] = pchild
        values[rows] = child
        origin[rows] = origin[rows] + 0.5 * side[rows, None] * np.stack([a, b], axis=1)
        side[rows] = 0.5 * side[rows]
    return best.result(evaluations)


def sector_search(cost_fn: CostFn, n_problems: int = 1, levels: int = 3) -> SearchResult:
    """Ramdaras' nine-sector search (sec. 4, Fig. 4), B problems in lockstep.

    Level 1 evaluates the 4 x 4 corners of nine sectors; each further level the 12 corners that
    are new inside the chosen sector. After ``levels`` levels the centre of the last chosen
    sector is evaluated and returned: 16 + 12 (levels - 1) + 1 evaluations per problem.
    """
    B, levels = check_integer("n_problems", n_problems), check_integer("levels", levels)
    offsets = np.arange(4) / 3.0
    ij = np.stack(np.meshgrid(np.arange(4), np.arange(4), indexing="ij"), -1).reshape(16, 2)
    origin = np.zeros((B, 2))
    side = 1.0
    values = np.full((B, 4, 4), np.nan)
    rows = np.arange(B)
    evaluations = 0
    for _ in range(levels):
        new = ij[np.isnan(values[0]).reshape(-1)]
        u = origin[:, None, :] + side * offsets[new]
        costs, _ = _call(cost_fn, rows, u)
        evaluations += costs.size
        values[:, new[:, 0], new[:, 1]] = costs
        # Summed corner cost of each sector (a, b) in {0, 1, 2}^2; take the lowest.
        v = values
        total = v[:, :3, :3] + v[:, 1:, :3] + v[:, :3, 1:] + v[:, 1:, 1:]
        s = np.argmin(total.reshape(B, 9), axis=1)
        a, b = s // 3, s % 3
        child = np.full((B, 4, 4), np.nan)
        for da, db in _CORNERS:
            child[:, 3 * da, 3 * db] = v[rows, a + da, b + db]
        values = child
        origin = origin + side / 3.0 * np.stack([a, b], axis=1)
        side = side / 3.0
    centre = origin[:, None, :] + 0.5 * side
    costs, aux = _call(cost_fn, rows, centre)
    best = _Best(B)
    best.offer(rows, centre, costs, aux)
    return best.result(evaluations + costs.size)


def evolution_search(
    cost_fn: CostFn,
    dim: int,
    rng: np.random.Generator | int | None = None,
    *,
    popsize: int = 15,
    maxiter: int = 100,
    tol: float = 1e-6,
    x0: np.ndarray | None = None,
) -> SearchResult:
    """Differential evolution (scipy) over [0, 1]^dim for one problem (Hernandez sec. 3.3.4):
    ``cost_fn`` gets rows = [0] and a whole population ``u`` ``(1, P, dim)``; ``x0`` ``(dim,)``
    seeds the population (e.g. "hold course")."""
    from scipy.optimize import differential_evolution

    dim = check_integer("dim", dim)
    popsize, maxiter = check_integer("popsize", popsize), check_integer("maxiter", maxiter)
    rows = np.zeros(1, dtype=int)
    best = _Best(1, dim)
    count = [0]

    def f(x: np.ndarray) -> np.ndarray:
        u = np.atleast_2d(np.asarray(x, dtype=float).T)[None]  # (1, P, dim)
        costs, aux = _call(cost_fn, rows, u)
        count[0] += costs.size
        best.offer(rows, u, costs, aux)
        return costs[0]

    seed = rng if rng is None or isinstance(rng, np.random.Generator) else int(rng)
    differential_evolution(
        f,
        bounds=[(0.0, 1.0)] * dim,
        popsize=popsize,
        maxiter=maxiter,
        tol=float(tol),
        polish=False,
        vectorized=True,
        updating="deferred",
        rng=seed,
        x0=None if x0 is None else np.clip(np.asarray(x0, dtype=float), 0.0, 1.0),
    )
    return best.result(count[0])


SEARCHES = ("grid", "quadrant", "sector", "evolution")
