"""Where a sensor looks in one scan: a bearing sector ``centre +- width / 2`` [rad, world frame]
and ranges ``[r_min, r_max]`` [m]; ``width`` 2 pi is all around. The simulator draws clutter
over it, the tracker and the bounds count a target inside it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["FieldOfView", "sector_coverage"]

_erf = np.vectorize(math.erf, otypes=[float])


@dataclass(frozen=True)
class FieldOfView:
    """Where a sensor looked at one epoch: the bearing sector ``centre +- width / 2`` [rad,
    world frame, from +x counter-clockwise] and ranges ``[r_min, r_max]`` [m]. ``width`` 2 pi:
    all around."""

    centre: float = 0.0
    width: float = 2.0 * math.pi
    r_min: float = 0.0
    r_max: float = math.inf

    @property
    def all_around(self) -> bool:
        return self.width >= 2.0 * math.pi

    def contains(self, target_pv: np.ndarray, sensor_pv: np.ndarray) -> np.ndarray:
        """Whether pv states ``(..., 4)`` are inside, seen from the sensor's pv ``(4,)``."""
        X = np.asarray(target_pv, dtype=float)
        dx = X[..., 0] - sensor_pv[0]
        dy = X[..., 2] - sensor_pv[2]
        r = np.hypot(dx, dy)
        inside = (r >= self.r_min) & (r <= self.r_max)
        if self.width < 2.0 * math.pi:
            off = np.angle(np.exp(1j * (np.arctan2(dy, dx) - self.centre)))
            inside &= np.abs(off) <= 0.5 * self.width
        return inside

    def coverage(self, mean: np.ndarray, cov: np.ndarray, sensor_pv: np.ndarray) -> np.ndarray:
        """Probability ``(T,)`` that targets N(mean, cov) (pv ``(T, 4)``, ``(T, 4, 4)``) lie in
        the bearing sector, seen from ``sensor_pv`` ``(4,)`` (:func:`sector_coverage`); 1 all
        around. The ranges are not counted."""
        means = np.asarray(mean, dtype=float)
        if self.all_around:
            return np.ones(means.shape[0])
        s = np.asarray(sensor_pv, dtype=float)
        bearing = np.arctan2(means[:, 2] - s[2], means[:, 0] - s[0])
        off = np.angle(np.exp(1j * (bearing - self.centre)))
        return sector_coverage(self.width, off, means, cov, s)


def sector_coverage(
    width: float, offset: np.ndarray | float, x: np.ndarray, P: np.ndarray, sensor_pv: np.ndarray
) -> np.ndarray:
    """Probability that a target N(x, P) lies inside a bearing sector ``width`` wide whose
    centre is ``offset`` [rad] off the bearing of x, seen from sensor pvs: with the linearised
    bearing variance sigma_b^2 = h P h^T (h = (-dy, 0, dx, 0) / r^2),
    (erf((w/2 - offset) / (sqrt(2) sigma_b)) + erf((w/2 + offset) / (sqrt(2) sigma_b))) / 2.
    x ``(..., 4)``, P ``(..., 4, 4)``, sensor_pv ``(..., 4)`` and offset broadcast; returns
    ``(...)``."""
    pv = np.asarray(sensor_pv, dtype=float)
    x = np.asarray(x, dtype=float)
    dx, dy = x[..., 0] - pv[..., 0], x[..., 2] - pv[..., 2]
    r2 = np.maximum(dx * dx + dy * dy, 1e-300)
    z = np.zeros_like(dx)
    h = np.stack([-dy / r2, z, dx / r2, z], axis=-1)
    var = np.einsum("...i,...ij,...j->...", h, np.asarray(P, dtype=float), h)
    spread = np.sqrt(np.maximum(var, 1e-300)) * math.sqrt(2.0)
    half, off = 0.5 * width, np.asarray(offset, dtype=float)
    return np.asarray(0.5 * (_erf((half - off) / spread) + _erf((half + off) / spread)))
