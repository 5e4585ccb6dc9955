"""The planner criteria: one registry, one vocabulary, for every planner and the scenario files.

A criterion is the scalar a planner minimises, of a pv covariance ``P`` ``(..., 4, 4)`` (a
PCRLB J^{-1} or an MRE prediction, Ramdaras eq. 23) and for some of the predicted state ``x``
``(4,)``. Uses: ``"pcrlb"`` (Hernandez sec. 3-4, ``planner.criterion`` with ``planner.cost:
pcrlb``), ``"positioning"`` (Ramdaras sec. 4, with ``planner.cost: mre``), ``"selection"``
(Ramdaras eq. 27, ``planner.selection.criterion``). Built in:

| name | computed as | pcrlb | positioning | selection |
|---|---|---|---|---|
| ``b_k`` | Hernandez eq. 10, max(sqrt(P(1,1)), sqrt(P(3,3))) | yes | yes | |
| ``trace`` | tr(P) | yes | yes | |
| ``trace_pos`` | P(1,1) + P(3,3), mean squared position error (GOSPA's, p = 2) | yes | yes | |
| ``det_pos`` | Ramdaras eq. 24, det of the position block | yes | yes | yes |
| ``heading`` | Ramdaras eq. 25, H^c P H^c^T, H^c of eq. 26 at x | | yes | yes |
| ``range``, ``doppler``, ``bearing`` | the same, other rows of eq. 26 | | yes | yes |

:func:`register_criterion` adds one, usable from a scenario file at once (every planner and the
schema look names up here). A criterion that needs the target state cannot serve PCRLB planning
(the bound has no single predicted state). See docs/extending.md, "A planner criterion".
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Final

import numpy as np

from activetrack.bounds.costs import (
    EQ26_ROWS,
    criterion_variance,
    position_determinant,
    position_trace,
    position_trace_of_information,
    rmse_bound,
    rmse_bound_of_information,
    trace_cost,
)
from activetrack.bounds.pcrlb import covariance_bound

__all__ = [
    "PCRLB",
    "POSITIONING",
    "SELECTION",
    "USES",
    "Criterion",
    "criteria",
    "criterion_names",
    "get_criterion",
    "register_criterion",
    "unregister_criterion",
]

PCRLB: Final = "pcrlb"
POSITIONING: Final = "positioning"
SELECTION: Final = "selection"
# What a criterion can apply to, and how the error messages name it.
USES: Final = {
    PCRLB: "PCRLB planning",
    POSITIONING: "MRE positioning",
    SELECTION: "MRE selection",
}

# cost(P (..., 4, 4), x (4,) or None) -> (...); information_cost(J (..., 4, 4)) -> (...);
# state_problem(x (4,)) -> why the criterion is undefined at x, or None.
CovarianceCost = Callable[[np.ndarray, np.ndarray | None], np.ndarray]
InformationCost = Callable[[np.ndarray], np.ndarray]
StateProblem = Callable[[np.ndarray], str | None]

_NAME = re.compile(r"[a-z][a-z0-9_]{0,31}")


@dataclass(frozen=True)
class Criterion:
    """One planner criterion: ``name`` (lower case, digits, '_'), ``cost(P, x)`` of pv
    covariances ``(..., 4, 4) -> (...)`` (x the predicted pv, None when not ``needs_state``),
    ``uses`` a subset of ``USES``, ``definition`` with the paper's equation, optional
    ``information_cost`` from J directly (default ``cost(J^{-1}, None)``) and
    ``state_problem``, why the criterion is undefined at a state (e.g. heading at rest)."""

    name: str
    cost: CovarianceCost
    uses: frozenset[str]
    definition: str
    needs_state: bool = False
    information_cost: InformationCost | None = None
    state_problem: StateProblem | None = None

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and _NAME.fullmatch(self.name)):
            raise ValueError(
                f"criterion name must be 1-32 lower-case letters, digits and '_', starting "
                f"with a letter, got {self.name!r}"
            )
        uses = frozenset(self.uses)
        if not uses or not uses <= set(USES):
            raise ValueError(f"criterion uses must be a non-empty subset of {tuple(USES)}")
        object.__setattr__(self, "uses", uses)
        if not callable(self.cost):
            raise ValueError(f"criterion {self.name!r}: cost must be callable")
        if self.needs_state and PCRLB in uses:
            raise ValueError(
                f"criterion {self.name!r} needs the target state: it cannot apply to "
                f"{PCRLB!r} (the bound has no single predicted state)"
            )

    def applies_to(self, use: str) -> bool:
        return use in self.uses

    def of_covariance(self, P: np.ndarray, x: np.ndarray | None = None) -> np.ndarray:
        """The criterion of covariances ``P`` ``(..., 4, 4) -> (...)``, x the predicted pv."""
        if x is None and self.needs_state:
            raise ValueError(f"x (the predicted target pv state) is required for {self.name!r}")
        return self.cost(P, x)

    def of_information(self, J: np.ndarray) -> np.ndarray:
        """The criterion of the bound J^{-1} for information matrices ``(..., 4, 4) -> (...)``."""
        if self.information_cost is not None:
            return self.information_cost(J)
        return self.cost(covariance_bound(J), None)


_REGISTRY: dict[str, Criterion] = {}
_BUILT_IN: set[str] = set()


def register_criterion(criterion: Criterion, *, replace: bool = False) -> Criterion:
    """Add ``criterion`` to the registry (``replace``: over one of the same name, not a built-in
    one). Returns it, so a module can keep ``MY = register_criterion(Criterion(...))``."""
    if not isinstance(criterion, Criterion):
        raise ValueError(f"criterion must be a Criterion, got {type(criterion).__name__}")
    if criterion.name in _BUILT_IN or (criterion.name in _REGISTRY and not replace):
        raise ValueError(f"criterion {criterion.name!r} is already registered")
    _REGISTRY[criterion.name] = criterion
    return criterion


def unregister_criterion(name: str) -> None:
    """Remove a registered criterion (not a built-in one); unknown names are an error."""
    if name in _BUILT_IN or name not in _REGISTRY:
        raise ValueError(f"criterion {name!r} is not a registered, removable criterion")
    del _REGISTRY[name]


def criteria(*uses: str) -> tuple[Criterion, ...]:
    """The registered criteria in registration order; with ``uses``, those applying to any."""
    return tuple(c for c in _REGISTRY.values() if not uses or not c.uses.isdisjoint(uses))


def criterion_names(*uses: str) -> tuple[str, ...]:
    """Names of :func:`criteria` (``uses``), in registration order."""
    return tuple(c.name for c in criteria(*uses))


def get_criterion(name: str, *uses: str, what: str = "criterion") -> Criterion:
    """The criterion ``name``, which must apply to one of ``uses`` (any use if none given).

    Raises ValueError naming ``what`` and the allowed names for those uses."""
    found = _REGISTRY.get(name) if isinstance(name, str) else None
    if found is None or (uses and found.uses.isdisjoint(uses)):
        where = " or ".join(USES[u] for u in uses)
        suffix = f" for {where}" if uses else ""
        raise ValueError(f"{what} must be one of {criterion_names(*uses)}{suffix}, got {name!r}")
    return found


def _moving(x: np.ndarray) -> str | None:
    if math.hypot(x[1], x[3]) == 0.0:
        return "needs a moving target, but the predicted target velocity is zero"
    return None


def _off_origin(x: np.ndarray) -> str | None:
    if math.hypot(x[0], x[2]) == 0.0:
        return (
            "is taken from the origin (Ramdaras eq. 26), where the target's predicted position lies"
        )
    return None


def _eq25(row: str, P: np.ndarray, x: np.ndarray | None) -> np.ndarray:
    if x is None:
        raise ValueError(f"x (the predicted target pv state) is required for {row!r}")
    return criterion_variance(row, P, x)


def _register_built_ins() -> None:
    both_mre = {POSITIONING, SELECTION}
    built_in = [
        Criterion(
            "b_k",
            lambda P, x: rmse_bound(P),
            frozenset({PCRLB, POSITIONING}),
            "Hernandez eq. 10: max(sqrt(P(1,1)), sqrt(P(3,3))), the larger position RMSE bound",
            information_cost=rmse_bound_of_information,
        ),
        Criterion("trace", lambda P, x: trace_cost(P), frozenset({PCRLB, POSITIONING}), "tr(P)"),
        Criterion(
            "trace_pos",
            lambda P, x: position_trace(P),
            frozenset({PCRLB, POSITIONING}),
            "P(1,1) + P(3,3), the mean squared position error: what GOSPA's localisation "
            "(order p = 2) counts for a held track",
            information_cost=position_trace_of_information,
        ),
        Criterion(
            "det_pos",
            lambda P, x: position_determinant(P),
            frozenset({PCRLB, *both_mre}),
            "Ramdaras eq. 24: det of the position block [[P(1,1), P(1,3)], [P(3,1), P(3,3)]]",
        ),
    ]
    descriptions = {
        "heading": "the course psi = atan2(ydot, xdot)",
        "range": "the range from the origin",
        "doppler": "the range rate seen from the origin",
        "bearing": "the bearing from the origin",
    }
    for row in EQ26_ROWS:
        built_in.append(
            Criterion(
                row,
                partial(_eq25, row),
                frozenset(both_mre),
                f"Ramdaras eq. 25: H^c P H^c^T, the variance of {descriptions[row]} "
                f"(H^c of eq. 26 at the predicted target state)",
                needs_state=True,
                state_problem=_moving if row == "heading" else _off_origin,
            )
        )
    for c in built_in:
        register_criterion(c)
        _BUILT_IN.add(c.name)


_register_built_ins()
