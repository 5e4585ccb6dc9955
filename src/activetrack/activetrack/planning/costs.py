"""PCRLB costs of candidate manoeuvres over a planning horizon (glue to ``activetrack.bounds``).

A :class:`HorizonModel` holds what one decision at epoch k needs: the linear target dynamics
(F, Q), the target samples at epochs k+1..k+R (Hernandez sec. 3.2: the prior, or the tracker's
posterior for renewals, pushed through the dynamics) and the information the platforms that are
*not* being optimised contribute at those epochs. Scoring candidates for the platform being
optimised is then one batched PCRLB step (Hernandez eq. 3 with eq. 8-9)::

    J_{k+r} = (Q + F J_{k+r-1}^{-1} F^T)^{-1} + J_Z^fixed(k+r) + J_Z^platform(k+r; candidates)

and a criterion of J^{-1} that applies to PCRLB planning (:mod:`activetrack.planning.criteria`:
``"b_k"``, eq. 10, ``"trace"``, ``"det_pos"``, Ramdaras eq. 24, or a registered one).
Every candidate J computed counts as one cost evaluation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from activetrack.arraytypes import ArrayLike
from activetrack.bounds.pcrlb import (
    check_dynamics,
    information_function,
    measurement_information,
    predicted_information,
)
from activetrack.planning.criteria import PCRLB, get_criterion

if TYPE_CHECKING:
    from activetrack.models.base import SensorModel

__all__ = ["HorizonModel", "InformationCache", "criterion_cost", "platform_information"]


def criterion_cost(criterion: str, J: np.ndarray) -> np.ndarray:
    """Criterion ``criterion`` of the bound J^{-1} for information matrices ``(..., 4, 4)``."""
    return get_criterion(criterion, PCRLB).of_information(J)


def platform_information(
    sensors: Sequence[SensorModel], pv: np.ndarray, samples: np.ndarray
) -> np.ndarray:
    """J_Z (Hernandez eq. 8-9) of one platform's sensors at pv states ``(..., 4)`` for target
    samples ``(M, 4)``: ``(..., 4, 4)``. All sensors of a platform sit at its pv."""
    pv = np.asarray(pv, dtype=float)
    if len(sensors) == 1:
        return measurement_information(sensors[0], pv, samples)
    states = np.broadcast_to(pv[..., None, :], (*pv.shape[:-1], len(sensors), 4))
    return measurement_information(tuple(sensors), states, samples)


class InformationCache:
    """One platform's own J_Z of whole candidate batches within a decision, keyed by epoch and
    positions, holding at most ``max_candidates`` candidates (then it stops adding: a long
    horizon scores millions, and a batch seen once is rarely seen again)."""

    def __init__(self, max_candidates: int = 100_000):
        self.max_candidates = int(max_candidates)
        self.candidates = 0
        self._store: dict[tuple[int, bytes], np.ndarray] = {}

    def get(self, key: tuple[int, bytes]) -> np.ndarray | None:
        return self._store.get(key)

    def put(self, key: tuple[int, bytes], J_Z: np.ndarray) -> None:
        if self.candidates + len(J_Z) <= self.max_candidates:
            self._store[key] = J_Z
            self.candidates += len(J_Z)


class HorizonModel:
    """Batched PCRLB steps and costs over epochs k+1..k+R for one platform being optimised.

    F, Q: ``(4, 4)`` target dynamics (eq. 2). samples: ``(R, M, 4)`` target samples at
    k+1..k+R. fixed_information: ``(R, 4, 4)`` J_Z of all other platforms at those epochs.
    sensors: the optimised platform's sensors. ``evaluations`` counts candidate PCRLB steps.

    ``cache``: an optional :class:`InformationCache` shared by the models of one platform within
    a decision (the coordinate descent over platforms optimises a platform again with the
    others' plans changed): the platform's own J_Z of a whole batch of candidate positions at an
    epoch is computed once and looked up when the same batch comes again (same numbers: the J_Z
    of a position does not depend on the other platforms).
    """

    def __init__(
        self,
        F: np.ndarray,
        Q: np.ndarray,
        samples: np.ndarray,
        fixed_information: ArrayLike,
        sensors: Sequence[SensorModel],
        criterion: str = "b_k",
        cache: InformationCache | None = None,
    ):
        self._criterion = get_criterion(criterion, PCRLB)
        self.F, self.Q = check_dynamics(F, Q, 4)  # once: the steps below trust them
        self.samples = np.asarray(samples, dtype=float)
        self.fixed = np.asarray(fixed_information, dtype=float)
        self.sensors = tuple(sensors)
        self.criterion = criterion
        self.evaluations = 0
        # Each sensor's J_Z of flat candidate batches (N, 4) -> (N, 4, 4): its compiled kernel
        # where it has one (bounds.pcrlb.information_function), resolved once per model.
        self._information = [information_function(s) for s in self.sensors]
        self._cache = cache

    @property
    def horizon(self) -> int:
        return self.samples.shape[0]

    def step(self, J_prev: np.ndarray, r: int, pv: np.ndarray) -> np.ndarray:
        """J at epoch k+1+r with the platform at ``pv`` ``(..., 4)``; J_prev broadcasts
        ``(..., 4, 4)``. Hernandez eq. 3."""
        return self.update(self.predict(J_prev), r, pv)

    def predict(self, J_prev: np.ndarray) -> np.ndarray:
        """The prediction part of eq. 3, (Q + F J_prev^{-1} F^T)^{-1}: it depends on J_prev
        only, so a search computes it once per J_prev and scores all candidates against it."""
        return predicted_information(np.asarray(J_prev, dtype=float), self.F, self.Q)

    def platform_information(self, r: int, pv: np.ndarray) -> np.ndarray:
        """The platform's own J_Z at epoch k+1+r for pv states ``(..., 4)``: ``(..., 4, 4)``
        (eq. 8-9, its sensors summed in order as :func:`platform_information` does)."""
        flat = np.ascontiguousarray(pv, dtype=float).reshape(-1, 4)
        cache = self._cache
        key = (r, flat.tobytes() if cache is not None else b"")
        J_Z = None if cache is None else cache.get(key)
        if J_Z is None:
            J_Z = np.zeros((flat.shape[0], 4, 4))
            for info in self._information:
                J_Z = J_Z + info(self.samples[r], flat)
            if cache is not None:
                cache.put(key, J_Z)
        return J_Z.reshape(*pv.shape[:-1], 4, 4)

    def update(self, J_pred: np.ndarray, r: int, pv: np.ndarray) -> np.ndarray:
        """``J_pred`` (from :meth:`predict`) plus J_Z at epoch k+1+r with the platform at
        ``pv`` ``(..., 4)`` and the others' fixed information."""
        pv = np.asarray(pv, dtype=float)
        J_Z = self.fixed[r] + self.platform_information(r, pv)
        self.evaluations += math.prod(pv.shape[:-1])
        return J_pred + J_Z

    def cost(self, J: np.ndarray) -> np.ndarray:
        """The criterion of J^{-1}, ``(..., 4, 4) -> (...)``."""
        return self._criterion.of_information(J)
