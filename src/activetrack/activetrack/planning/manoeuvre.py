"""Platform manoeuvre model of Hernandez sec. 3.3.1 and 5.1.

At epoch k a platform turns by ``dpsi`` in [-dpsi_max, dpsi_max], sets a speed ``v'`` in
[max(v_min, v - dv_max), min(v_max, v + dv_max)] and flies a constant-velocity leg of T s. The
searches explore the reachable annular sector through the unit square u in [0, 1]^2::

    dpsi = (2 u_psi - 1) dpsi_max,    v' = v_lo + u_v (v_hi - v_lo)

(u = (0.5, .) is straight ahead). Ramdaras' limits (sec. 5) enter as dv_max = a_max T,
dpsi_max = psi_rate_max T. Manoeuvres are stored as ``(dpsi, v')``, ``(..., 2)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np

from activetrack.angles import wrap_angle
from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_finite

if TYPE_CHECKING:
    from activetrack.models.base import SensorModel

__all__ = [
    "PlannerPlatform",
    "PlatformLimits",
    "hold_course",
    "rollout",
    "speed_interval",
    "step_platform",
    "unit_to_manoeuvre",
]


@dataclass(frozen=True)
class PlatformLimits:
    """Per-epoch manoeuvre limits: |dpsi| <= dpsi_max (rad), |v' - v| <= dv_max (m/s),
    v_min <= v' <= v_max (Hernandez sec. 5.1: pi/10, 10 m/s, [50, 200] m/s)."""

    dpsi_max: float
    dv_max: float
    v_min: float
    v_max: float

    def __post_init__(self) -> None:
        for name in ("dpsi_max", "dv_max", "v_min", "v_max"):
            value = float(getattr(self, name))
            if not math.isfinite(value) or value < 0.0:
                raise ValueError(f"limits.{name} must be finite and >= 0, got {value!r}")
            object.__setattr__(self, name, value)
        if self.dpsi_max > math.pi:
            raise ValueError(f"limits.dpsi_max must be in [0, pi], got {self.dpsi_max!r}")
        if self.v_max <= 0.0 or self.v_min > self.v_max:
            raise ValueError(
                f"limits: need 0 <= v_min <= v_max and v_max > 0, got v_min={self.v_min}, "
                f"v_max={self.v_max}"
            )


def speed_interval(speed: ArrayLike, limits: PlatformLimits) -> tuple[FloatArray, FloatArray]:
    """Reachable speeds [max(v_min, v - dv_max), min(v_max, v + dv_max)] from ``speed``
    ``(...)``; a speed outside [v_min, v_max] comes back as far as dv_max allows."""

    v = np.asarray(speed, dtype=float)
    lo = np.clip(v - limits.dv_max, limits.v_min, limits.v_max)
    hi = np.clip(v + limits.dv_max, limits.v_min, limits.v_max)
    return lo, hi


def unit_to_manoeuvre(u: ArrayLike, speed: ArrayLike, limits: PlatformLimits) -> FloatArray:
    """Unit-square points ``u`` ``(..., 2)`` to manoeuvres (dpsi, v') ``(..., 2)`` from the
    speed before the manoeuvre ``(...)``."""
    u = np.asarray(u, dtype=float)
    lo, hi = speed_interval(speed, limits)
    dpsi = (2.0 * u[..., 0] - 1.0) * limits.dpsi_max
    v = lo + u[..., 1] * (hi - lo)
    return np.stack(np.broadcast_arrays(dpsi, v), axis=-1)


def manoeuvre_to_unit(manoeuvre: ArrayLike, speed: ArrayLike, limits: PlatformLimits) -> FloatArray:
    """Inverse of :func:`unit_to_manoeuvre` (a degenerate speed interval maps to u_v = 0.5)."""
    m = np.asarray(manoeuvre, dtype=float)
    lo, hi = speed_interval(speed, limits)
    u_psi = 0.5 if limits.dpsi_max == 0.0 else 0.5 * (m[..., 0] / limits.dpsi_max + 1.0)
    width = hi - lo
    u_v = np.where(width > 0.0, (m[..., 1] - lo) / np.where(width > 0.0, width, 1.0), 0.5)
    return np.stack(np.broadcast_arrays(u_psi, u_v), axis=-1)


def step_platform(
    pv: ArrayLike, heading: ArrayLike, manoeuvre: ArrayLike, dt: float
) -> tuple[FloatArray, FloatArray]:
    """pv ``(..., 4)`` at k+1 and the new heading after manoeuvres (dpsi, v') ``(..., 2)`` and a
    constant-velocity leg; pv, heading ``(...)`` and manoeuvre broadcast."""
    pv = np.asarray(pv, dtype=float)
    m = np.asarray(manoeuvre, dtype=float)
    psi = wrap_angle(np.asarray(heading, dtype=float) + m[..., 0])
    vx = m[..., 1] * np.cos(psi)
    vy = m[..., 1] * np.sin(psi)
    x = pv[..., 0] + vx * dt
    y = pv[..., 2] + vy * dt
    return np.stack(np.broadcast_arrays(x, vx, y, vy), axis=-1), psi


def rollout(
    pv: ArrayLike, heading: ArrayLike, manoeuvres: ArrayLike, dt: float
) -> tuple[FloatArray, FloatArray]:
    """pv ``(..., R, 4)`` and headings ``(..., R)`` at k+1..k+R for manoeuvres ``(..., R, 2)``."""
    m = np.asarray(manoeuvres, dtype=float)
    pvs, headings = [], []
    p, h = np.asarray(pv, dtype=float), np.asarray(heading, dtype=float)
    for r in range(m.shape[-2]):
        p, h = step_platform(p, h, m[..., r, :], dt)
        pvs.append(p)
        headings.append(h)
    return np.stack(pvs, axis=-2), np.stack(headings, axis=-1)


def hold_course(speed: float, limits: PlatformLimits, steps: int) -> FloatArray:
    """The manoeuvre sequence "keep heading and speed" ``(steps, 2)`` (speed clipped into the
    reachable interval when it lies outside [v_min, v_max])."""
    lo, hi = speed_interval(speed, limits)
    v = float(np.clip(speed, lo, hi))
    out = np.zeros((int(steps), 2))
    out[:, 1] = v
    # Later legs start from v itself, which is then inside [v_min, v_max] or moving towards it.
    for r in range(1, int(steps)):
        lo, hi = speed_interval(out[r - 1, 1], limits)
        out[r, 1] = float(np.clip(out[r - 1, 1], lo, hi))
    return out


@dataclass(frozen=True)
class PlannerPlatform:
    """A platform at the decision epoch; ``limits=None``: it holds course. heading (rad from
    +x) and speed default to the pv velocity's (give heading for a platform at rest)."""

    platform_id: str
    pv: np.ndarray
    sensors: tuple[SensorModel, ...]
    limits: PlatformLimits | None = None
    heading: float | None = None
    speed: float | None = None

    def __post_init__(self) -> None:
        pv = require_finite("platforms.pv", self.pv)
        if pv.shape != (4,):
            raise ValueError(f"platforms.pv must be a pv vector of shape (4,), got {pv.shape}")
        object.__setattr__(self, "pv", pv)
        sensors = tuple(self.sensors)
        # What planning asks of a sensor: its information and its measurement model.
        needed = ("fisher_information", "jacobian", "R")
        if not sensors or not all(all(hasattr(s, m) for m in needed) for s in sensors):
            raise ValueError(
                f"platforms.sensors of {self.platform_id!r} must hold at least one sensor model"
            )
        object.__setattr__(self, "sensors", sensors)
        if self.limits is not None and not isinstance(self.limits, PlatformLimits):
            raise ValueError("platforms.limits must be a PlatformLimits or None")
        speed = math.hypot(pv[1], pv[3]) if self.speed is None else float(self.speed)
        if not (math.isfinite(speed) and speed >= 0.0):
            raise ValueError(f"platforms.speed must be finite and >= 0, got {self.speed!r}")
        if self.heading is None:
            if speed == 0.0 and self.limits is not None:
                raise ValueError(
                    f"platforms.heading is required for platform {self.platform_id!r} at rest"
                )
            heading = math.atan2(pv[3], pv[1])
        else:
            heading = float(self.heading)
            if not math.isfinite(heading):
                raise ValueError(f"platforms.heading must be finite, got {self.heading!r}")
        object.__setattr__(self, "heading", heading)
        object.__setattr__(self, "speed", speed)

    @property
    def controllable(self) -> bool:
        return self.limits is not None

    @property
    def heading_and_speed(self) -> tuple[float, float]:
        """(heading, speed) as resolved on construction (never None)."""
        return cast(float, self.heading), cast(float, self.speed)

    def path(self, dt: float, steps: int, plan: np.ndarray | None = None) -> FloatArray:
        """pv at epochs k+1..k+steps ``(steps, 4)`` flying ``plan`` ``(steps, 2)``, or without
        one constant-velocity legs along the pv velocity (how a platform without limits
        holds course)."""
        if plan is None:
            legs = np.arange(1, int(steps) + 1)[:, None] * dt
            return self.pv + legs * np.array([self.pv[1], 0.0, self.pv[3], 0.0])
        return rollout(self.pv, self.heading_and_speed[0], plan, dt)[0]
