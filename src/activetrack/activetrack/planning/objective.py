"""The planning objective: a weighted sum of terms, each a cost of the states along the
horizon (J of Hernandez eq. 3 or P of Ramdaras eq. 23, one per track)::

    V = sum_i w_i V_i,  V_i = sum_{r=1..R} g_i(state_{k+r})   (legs "sum": Hernandez eq. 11, 15-16)
                        V_i = g_i(state_{k+R})                 (legs "final")

A term is anything with ``weight``, ``legs`` and ``cost(state, level) -> (...)`` (level
0-based), so a new one plugs in without touching the search or the coordinator. The built-in
terms take a criterion of each track's state ``(..., T, 4, 4)`` and combine the tracks by
:class:`TrackAggregate` (worst, or priority-weighted sum); one target is T = 1.
:class:`ExpectedGospaTerm` weighs the tracks' expected GOSPA split of a rollout stage
(:mod:`activetrack.planning.gospa_rollout`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final, Protocol

import numpy as np

from activetrack.arraytypes import ArrayLike
from activetrack.planning.criteria import Criterion

__all__ = [
    "AGGREGATES",
    "FINAL",
    "SUM",
    "TIE_BREAK",
    "CovarianceTerm",
    "ExpectedGospaTerm",
    "InformationTerm",
    "Objective",
    "Term",
    "TrackAggregate",
    "aggregate_costs",
    "check_aggregate",
]

SUM: Final = "sum"
FINAL: Final = "final"
# Searching for the worst track alone, the other tracks should still decide when no candidate
# moves the worst one (e.g. no sensor of the platform serves it), instead of the search's first
# candidate (a hard turn) winning a tie: max_t c_t + TIE_BREAK sum_t c_t.
TIE_BREAK: Final = 1e-6
AGGREGATES: Final = ("worst", "weighted_sum")


def check_aggregate(aggregate: str) -> str:
    """``aggregate`` if it is one of :data:`AGGREGATES`, else ValueError."""
    if aggregate not in AGGREGATES:
        raise ValueError(f"aggregate must be one of {AGGREGATES}, got {aggregate!r}")
    return aggregate


def aggregate_costs(costs: ArrayLike, weights: ArrayLike, aggregate: str) -> np.ndarray:
    """Per-track costs ``(..., T)`` to one: ``"worst"`` max_t, ``"weighted_sum"`` sum_t w_t c_t
    (``weights`` ``(T,)``, the tracks' priorities)."""
    c = np.asarray(costs, dtype=float)
    if check_aggregate(aggregate) == "worst":
        return c[..., 0] if c.shape[-1] == 1 else np.max(c, axis=-1)  # one track: no reduction
    return np.sum(c * np.asarray(weights, dtype=float), axis=-1)


class Term(Protocol):
    """One term of an :class:`Objective`."""

    @property
    def weight(self) -> float: ...

    @property
    def legs(self) -> str:
        """:data:`SUM` (every leg counts) or :data:`FINAL` (the state after the last leg)."""
        ...

    def cost(self, state: np.ndarray, level: int) -> np.ndarray:
        """The cost of states reached by leg ``level`` (0-based): leading axes kept."""
        ...


@dataclass(frozen=True)
class Objective:
    """sum_i w_i V_i over ``terms`` (module docstring); at least one term."""

    terms: tuple[Term, ...]

    def __post_init__(self) -> None:
        terms = tuple(self.terms)
        if not terms:
            raise ValueError("objective: terms must hold at least one term")
        for term in terms:
            if term.legs not in (SUM, FINAL):
                raise ValueError(f"objective: legs must be {SUM!r} or {FINAL!r}, got {term.legs!r}")
            if not (math.isfinite(term.weight) and term.weight >= 0.0):
                raise ValueError(f"objective: weight must be finite and >= 0, got {term.weight!r}")
        object.__setattr__(self, "terms", terms)

    def leg_cost(self, state: np.ndarray, level: int, horizon: int) -> np.ndarray | None:
        """sum_i w_i g_i(state) over the terms counted at leg ``level`` of ``horizon``; None
        when none is (a leg before the last with terminal terms only)."""
        total = None
        for term in self.terms:
            if term.legs == SUM or level == horizon - 1:
                c = term.cost(state, level)
                c = c if term.weight == 1.0 else term.weight * c
                total = c if total is None else total + c
        return total

    def along(self, states: Sequence[np.ndarray]) -> float:
        """The objective of one state per leg ``states`` (k+1..k+R, of one candidate each: the
        plans already chosen), the legs' costs added in order."""
        total = 0.0
        for r, state in enumerate(states):
            c = self.leg_cost(state, r, len(states))
            if c is not None:
                total += float(c.item())
        return total


@dataclass(frozen=True)
class TrackAggregate:
    """Per-track costs ``(..., T)`` to one (:func:`aggregate_costs`): ``"worst"`` max_t c_t
    (plus ``tie_break`` sum_t c_t, see :data:`TIE_BREAK`) or ``"weighted_sum"`` sum_t w_t c_t
    with ``weights`` ``(T,)``, the tracks' priorities."""

    aggregate: str = "worst"
    weights: np.ndarray = field(default_factory=lambda: np.ones(1))
    tie_break: float = 0.0

    def __post_init__(self) -> None:
        check_aggregate(self.aggregate)
        w = np.asarray(self.weights, dtype=float)
        if w.ndim != 1 or not np.all(np.isfinite(w)):
            raise ValueError(f"weights must be a finite vector (T,), got {self.weights!r}")
        if not (math.isfinite(self.tie_break) and self.tie_break >= 0.0):
            raise ValueError(f"tie_break must be finite and >= 0, got {self.tie_break!r}")
        object.__setattr__(self, "weights", w)

    def __call__(self, costs: np.ndarray) -> np.ndarray:
        total = aggregate_costs(costs, self.weights, self.aggregate)
        if self.aggregate == "worst" and self.tie_break:
            total = total + self.tie_break * np.sum(costs, axis=-1)
        return total


@dataclass(frozen=True)
class InformationTerm:
    """``criterion`` of each track's PCRLB bound J^{-1} (Hernandez eq. 10 for ``"b_k"``): state
    J ``(..., T, 4, 4)`` (eq. 3), tracks combined by ``tracks``; by default summed over the
    legs (eq. 15-16)."""

    criterion: Criterion
    tracks: TrackAggregate = field(default_factory=TrackAggregate)
    legs: str = SUM
    weight: float = 1.0

    def cost(self, state: np.ndarray, level: int) -> np.ndarray:
        return self.tracks(self.criterion.of_information(state))


@dataclass(frozen=True)
class CovarianceTerm:
    """``criterion`` of each track's MRE covariance (Ramdaras eq. 23-26): state P ``(..., T, 4,
    4)``, at the predicted target states ``x`` ``(R, T, 4)`` of the legs (for the criteria of
    eq. 25-26 that need one), tracks combined by ``tracks``; by default the terminal cost
    (:func:`activetrack.planning.selection.plan_positions` says why)."""

    criterion: Criterion
    x: np.ndarray
    tracks: TrackAggregate = field(default_factory=TrackAggregate)
    legs: str = FINAL
    weight: float = 1.0

    def cost(self, state: np.ndarray, level: int) -> np.ndarray:
        if not self.criterion.needs_state:  # x unused: one call over every track's matrices
            return self.tracks(self.criterion.of_covariance(state, None))
        x = self.x[level]  # (T, 4)
        c = [self.criterion.of_covariance(state[..., t, :, :], x[t]) for t in range(len(x))]
        return self.tracks(np.stack(c, axis=-1))


@dataclass(frozen=True)
class ExpectedGospaTerm:
    """sum_t w_t (l_t + m_t + f_t): the tracks' expected GOSPA^p split (localisation, missed,
    false; :func:`activetrack.planning.expected_gospa.track_split`) of states ``(..., T, 3)``
    summed over a rollout's legs, ``weights`` ``(T,)`` the tracks' priorities (1 unless the
    scenario sets them: the terms' own weights are GOSPA's c, p and alpha)."""

    weights: np.ndarray
    legs: str = SUM
    weight: float = 1.0

    def cost(self, state: np.ndarray, level: int) -> np.ndarray:
        return np.einsum("...tk,t->...", state, np.asarray(self.weights, dtype=float))
