"""Paired comparison of two policies run on the same worlds (common random numbers).

Run r of policy A and run r of policy B share the run's world (targets, detections, clutter:
:mod:`activetrack.simulation.streams`), so the per-run difference ``a_r - b_r`` removes the
world's variance; its mean has a Student-t interval on R - 1 degrees of freedom.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from activetrack.arraytypes import ArrayLike
from activetrack.stats import t_quantile

__all__ = ["PairedDifference", "paired_difference"]


@dataclass(frozen=True)
class PairedDifference:
    """Mean of ``a_r - b_r`` over ``runs`` runs, its standard error and ``level`` interval
    ``[low, high]`` (NaN with fewer than two runs)."""

    mean: float
    stderr: float
    low: float
    high: float
    runs: int
    level: float = 0.95

    @property
    def resolved(self) -> bool:
        """Whether the interval excludes zero."""
        return bool(self.low > 0.0 or self.high < 0.0)

    def to_json(self) -> dict:
        return {
            "mean": self.mean,
            "stderr": self.stderr,
            "low": self.low,
            "high": self.high,
            "runs": self.runs,
            "level": self.level,
        }


def paired_difference(a: ArrayLike, b: ArrayLike, level: float = 0.95) -> PairedDifference:
    """The paired difference of per-run values ``a`` and ``b`` ``(R,)`` (run r of each on the
    same world). ValueError if their lengths differ, a value is not finite or ``level`` is
    outside (0, 1)."""
    a, b = np.asarray(a, dtype=float).reshape(-1), np.asarray(b, dtype=float).reshape(-1)
    if a.shape != b.shape:
        raise ValueError(f"a and b must have one value per run each, got {a.size} and {b.size}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError("a and b must be finite")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level}")
    d, n = a - b, a.size
    mean = float(d.mean()) if n else math.nan
    if n < 2:
        return PairedDifference(mean, math.nan, math.nan, math.nan, n, level)
    se = float(d.std(ddof=1) / math.sqrt(n))
    half = t_quantile(0.5 + level / 2.0, n - 1) * se
    return PairedDifference(mean, se, mean - half, mean + half, n, level)
