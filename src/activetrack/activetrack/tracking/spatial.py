"""Spatial indexes of the tracks' positions: which tracks a scan can hold, which pairs can be
close. Each gives a superset of the answer (a conservative radius on a k-d tree,
``scipy.spatial.cKDTree``); the caller then applies the exact test to it, so decisions are
those of the all-pairs test while the work grows with the neighbours, not with all tracks.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from activetrack.arraytypes import FloatArray
from activetrack.models.fov import FieldOfView

__all__ = ["FovIndex", "close_pairs", "largest_xy_eigenvalue"]

# Radii are widened by this relative amount (and _SLACK_M) so that a distance the tree computes
# a few ulps differently from the exact test never drops a candidate.
_WIDEN = 1e-9
_SLACK_M = 1e-6
_MIN_TREE = 32  # below this many points a brute-force test is cheaper than building a tree


def _kd_tree(points: FloatArray) -> Any:
    """scipy's k-d tree of ``points`` ``(k, 2)``, imported here: importing scipy.spatial adds
    process-wide warning filters."""
    from scipy.spatial import cKDTree

    return cKDTree(points)


class FovIndex:
    """The live tracks of one epoch by their position after the prediction, for the scans of
    the epoch: ``candidates`` are the tracks that may be inside a field of view (a superset,
    in the order given: the caller tests them exactly). Tracks keep moving as the scans update
    them (``moved``) and new ones start (``add``); the query radius grows by the largest
    displacement so far, and new tracks are always candidates."""

    def __init__(self, items: Sequence[object], positions: FloatArray):
        self.items = list(items)
        self.xy = np.asarray(positions, dtype=float).reshape(-1, 2)
        self._tree = _kd_tree(self.xy) if len(self.items) >= _MIN_TREE else None
        self._row = {id(item): k for k, item in enumerate(self.items)}
        self._added: list[object] = []
        self._moved = 0.0  # largest distance of a track from its indexed position

    def add(self, item: object) -> None:
        """A track started after the index was built (always a candidate)."""
        self._added.append(item)

    def moved(self, item: object, xy: FloatArray) -> None:
        """The track's position is now ``xy`` ``(2,)``."""
        row = self._row.get(id(item))
        if row is not None:
            d = math.hypot(float(xy[0] - self.xy[row, 0]), float(xy[1] - self.xy[row, 1]))
            self._moved = max(self._moved, d)

    def moved_many(self, items: Sequence[object], xy: FloatArray) -> None:
        """:meth:`moved` of each of ``items``, now at ``xy`` ``(k, 2)``, in one pass (numpy's
        hypot: within an ulp of math.hypot, inside the radius's widening)."""
        rows = [self._row.get(id(item), -1) for item in items]
        known = np.array([r >= 0 for r in rows], dtype=bool)
        if known.any():
            P = np.asarray(xy, dtype=float).reshape(-1, 2)[known]
            d = P - self.xy[np.array(rows)[known]]
            self._moved = max(self._moved, float(np.hypot(d[:, 0], d[:, 1]).max()))

    def candidates(self, fov: FieldOfView, sensor_pv: FloatArray) -> list[object]:
        """The tracks within ``fov.r_max`` of the sensor (all of them for an unbounded range),
        indexed ones in their order, then the added ones."""
        if self._tree is None or not math.isfinite(fov.r_max):
            return self.items + self._added
        radius = (fov.r_max + self._moved) * (1.0 + _WIDEN) + _SLACK_M
        rows = self._tree.query_ball_point([sensor_pv[0], sensor_pv[2]], radius)
        rows.sort()
        return [self.items[k] for k in rows] + self._added


def largest_xy_eigenvalue(covs: FloatArray) -> FloatArray:
    """The largest eigenvalue ``(T,)`` of each xy block of pv covariances ``(T, 4, 4)`` (closed
    form for a symmetric 2 x 2; equal to ``eigvalsh`` to round-off)."""
    a = covs[:, 0, 0]
    b = 0.5 * (covs[:, 0, 2] + covs[:, 2, 0])
    c = covs[:, 2, 2]
    return np.asarray(0.5 * (a + c) + np.hypot(0.5 * (a - c), b), dtype=float)


def close_pairs(xy: FloatArray, reach2: FloatArray) -> list[tuple[int, int]]:
    """The pairs ``(i, j)``, i < j, of points ``xy`` ``(T, 2)`` that may satisfy
    ``|xy_i - xy_j|^2 <= reach2_i + reach2_j`` (a superset: radii widened for round-off).
    With ``reach2 = d2_max * lambda_max(P_xy)`` this holds for every pair within Mahalanobis
    distance ``d2_max`` of each other through ``(P_i + P_j)^-1``."""
    T = xy.shape[0]
    if T < 2:
        return []
    r2 = np.asarray(reach2, dtype=float)
    if T < _MIN_TREE:
        return [(i, j) for i in range(T) for j in range(i + 1, T)]
    # |dp|^2 <= r2_i + r2_j <= 2 max(r2_i, r2_j): query each point with sqrt(r2_i + max r2)
    radius = np.sqrt(r2 + float(r2.max())) * (1.0 + _WIDEN) + _SLACK_M
    tree = _kd_tree(xy)
    out: list[tuple[int, int]] = []
    for i, rows in enumerate(tree.query_ball_point(xy, radius)):
        out.extend((i, j) if i < j else (j, i) for j in rows if j != i)
    return sorted(set(out))
