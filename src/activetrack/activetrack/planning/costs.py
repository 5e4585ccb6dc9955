"""The PCRLB of one target over a planning horizon for candidate manoeuvres (Hernandez eq. 3,
8-9). :class:`HorizonModel` (a stage of :func:`activetrack.planning.horizons.search_horizon`)
holds F, Q, the target samples at k+1..k+R (sec. 3.2) and the fixed platforms' information::

    J_{k+r} = (Q + F J_{k+r-1}^{-1} F^T)^{-1} + J_Z^fixed(k+r) + J_Z^platform(k+r; candidates)

:class:`FleetInformation` keeps every platform's J_Z along its current path for
:func:`activetrack.planning.multisensor.coordinate_platforms`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from activetrack.arraytypes import ArrayLike
from activetrack.bounds.pcrlb import (
    check_dynamics,
    information_function,
    measurement_information,
    pcrlb_step,
    predicted_information,
)

if TYPE_CHECKING:
    from activetrack.models.base import SensorModel
    from activetrack.planning.manoeuvre import PlannerPlatform

__all__ = ["FleetInformation", "HorizonModel", "InformationCache", "platform_information"]


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
    """Batched PCRLB steps over k+1..k+R of one target for the optimised platform (a
    :class:`HorizonStage`, state J ``(..., 1, 4, 4)``): F, Q ``(4, 4)`` (eq. 2), ``samples``
    ``(R, M, 4)``, ``fixed_information`` ``(R, 4, 4)`` the other platforms' J_Z, ``sensors``
    the platform's, ``cache`` its own J_Z per candidate batch (:class:`FleetInformation`)."""

    def __init__(
        self,
        F: np.ndarray,
        Q: np.ndarray,
        samples: np.ndarray,
        fixed_information: ArrayLike,
        sensors: Sequence[SensorModel],
        cache: InformationCache | None = None,
    ):
        self.F, self.Q = check_dynamics(F, Q, 4)  # once: the steps below trust them
        self.samples = np.asarray(samples, dtype=float)
        self.fixed = np.asarray(fixed_information, dtype=float)[:, None]  # (R, 1, 4, 4)
        self.sensors = tuple(sensors)
        # Each sensor's J_Z of flat candidate batches (N, 4) -> (N, 4, 4): its compiled kernel
        # where it has one (bounds.pcrlb.information_function), resolved once per model.
        self._information = [information_function(s) for s in self.sensors]
        self._cache = cache

    def prepare(self, J_prev: np.ndarray, level: int) -> np.ndarray:
        """The prediction part of eq. 3, (Q + F J_prev^{-1} F^T)^{-1}: it depends on J_prev
        only, so a search computes it once per J_prev and scores all candidates against it.
        ``(..., 1, 4, 4)``, one stack of matrices (compiled where the kernels are on)."""
        J_prev = np.asarray(J_prev, dtype=float)
        return predicted_information(J_prev.reshape(-1, 4, 4), self.F, self.Q).reshape(J_prev.shape)

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

    def advance(self, J_pred: np.ndarray, level: int, pv: np.ndarray) -> np.ndarray:
        """J at epoch k+1+level: ``J_pred`` (from :meth:`prepare`) plus the others' fixed J_Z
        and the platform's own at pv ``(..., 4)``: ``(..., 1, 4, 4)``."""
        J_Z = self.fixed[level] + self.platform_information(level, pv)[..., None, :, :]
        return J_pred + J_Z


class FleetInformation:
    """Every platform's J_Z at k+1..k+R along its current path (eq. 8-9) over the target
    ``samples`` ``(R, M, 4)``, and the :class:`HorizonModel` of the platform being optimised with
    the others' information fixed (the platform coordinator's stages,
    :class:`activetrack.planning.multisensor.PlatformStages`)."""

    def __init__(
        self,
        platforms: Sequence[PlannerPlatform],
        F: np.ndarray,
        Q: np.ndarray,
        samples: np.ndarray,
    ):
        self.platforms, self.F, self.Q, self.samples = tuple(platforms), F, Q, samples
        self.information = [np.zeros((len(samples), 4, 4)) for _ in self.platforms]
        # Each platform's own J_Z of candidate batches, kept across its optimisations in this
        # decision (HorizonModel's cache): a later pass often scores the same candidates again. A
        # single controllable platform is optimised once: nothing to share.
        shared = sum(p.limits is not None for p in self.platforms) > 1
        self.caches = [InformationCache() if shared else None for _ in self.platforms]

    def follow(self, i: int, path: np.ndarray) -> None:
        p, X = self.platforms[i], self.samples
        self.information[i] = np.stack(
            [platform_information(p.sensors, path[r], X[r]) for r in range(len(X))]
        )

    def stage(self, j: int) -> HorizonModel:
        info, n = self.information, len(self.platforms)
        fixed = sum(info[i] for i in range(n) if i != j) if n > 1 else np.zeros_like(info[j])
        return HorizonModel(
            self.F, self.Q, self.samples, fixed, self.platforms[j].sensors, self.caches[j]
        )

    def bound_information(self, J0: np.ndarray) -> np.ndarray:
        """J at epochs k+1..k+R ``(R, 4, 4)`` from J0 with every platform on its path (eq. 3)."""
        out, J = [], np.asarray(J0, dtype=float)
        for J_Z in sum(self.information, np.zeros_like(self.information[0])):
            J = pcrlb_step(J, self.F, self.Q, J_Z)
            out.append(J)
        return np.stack(out)
