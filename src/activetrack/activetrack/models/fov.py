"""Where a sensor looks: the field of view of one scan, as plain geometry.

A bearing sector ``centre +- width / 2`` [rad, world frame, from +x counter-clockwise] and the
ranges ``[r_min, r_max]`` [m]; ``width`` 2 pi is all around. The multi-target loop puts one on
every scan (the simulator draws clutter over it, the tracker and the bounds count a target
inside it); :class:`activetrack.models.clutter.ClutteredSensor` says where its sensor looks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["FieldOfView"]


@dataclass(frozen=True)
class FieldOfView:
    """Where a sensor looked at one epoch: the bearing sector ``centre +- width / 2`` [rad,
    world frame, from +x counter-clockwise] and ranges ``[r_min, r_max]`` [m]. ``width`` 2 pi:
    all around."""

    centre: float = 0.0
    width: float = 2.0 * math.pi
    r_min: float = 0.0
    r_max: float = math.inf

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
