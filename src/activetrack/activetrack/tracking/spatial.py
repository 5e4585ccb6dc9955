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
    them (``moved``) and new ones start (``add``, at their position: tested by distance, as
    few as a scan starts; one added without a position is a candidate of every scan); the
    query radius grows by the largest displacement so far."""

    def __init__(self, items: Sequence[object], positions: FloatArray):
        self.items = list(items)
        self.xy = np.asarray(positions, dtype=float).reshape(-1, 2)
        self._tree = _kd_tree(self.xy) if len(self.items) >= _MIN_TREE else None
        self._row = {id(item): k for k, item in enumerate(self.items)}
        self._added: list[object] = []
        # The added tracks' positions, rows [:len(_added)] of a buffer that doubles when full
        # (NaN: no position given): each scan reads them as one array, no list converted again.
        self._added_xy = np.empty((16, 2))
        self._added_row: dict[int, int] = {}
        self._moved = 0.0  # largest distance of a track from its indexed position

    def add(self, item: object, xy: FloatArray | None = None) -> None:
        """A track started after the index was built, at ``xy`` ``(2,)`` (None: a candidate
        of every scan)."""
        k = len(self._added)
        if k == self._added_xy.shape[0]:
            self._added_xy = np.concatenate((self._added_xy, np.empty_like(self._added_xy)))
        self._added_row[id(item)] = k
        self._added.append(item)
        self._added_xy[k] = (math.nan, math.nan) if xy is None else (float(xy[0]), float(xy[1]))

    def _origin(self, item: object) -> tuple[float, float] | None:
        """Where the index holds ``item`` (None: not held, or added without a position)."""
        row = self._row.get(id(item))
        if row is not None:
            return float(self.xy[row, 0]), float(self.xy[row, 1])
        row = self._added_row.get(id(item))
        if row is None:
            return None
        x, y = self._added_xy[row].tolist()
        return None if math.isnan(x) else (x, y)

    def moved(self, item: object, xy: FloatArray) -> None:
        """The track's position is now ``xy`` ``(2,)``."""
        origin = self._origin(item)
        if origin is not None:
            d = math.hypot(float(xy[0]) - origin[0], float(xy[1]) - origin[1])
            if not math.isnan(d):
                self._moved = max(self._moved, d)

    def moved_many(self, items: Sequence[object], xy: FloatArray) -> None:
        """:meth:`moved` of each of ``items``, now at ``xy`` ``(k, 2)``, in one pass (numpy's
        hypot: within an ulp of math.hypot, inside the radius's widening)."""
        origins = [self._origin(item) for item in items]
        known = np.array([o is not None for o in origins], dtype=bool)
        if known.any():
            P = np.asarray(xy, dtype=float).reshape(-1, 2)[known]
            d = P - np.array([o for o in origins if o is not None])
            dist = np.hypot(d[:, 0], d[:, 1])
            if not np.isnan(dist).all():
                self._moved = max(self._moved, float(np.nanmax(dist)))

    def candidates(self, fov: FieldOfView, sensor_pv: FloatArray) -> list[object]:
        """The tracks within ``fov.r_max`` of the sensor (all of them for an unbounded range),
        indexed ones in their order, then the added ones in theirs."""
        if self._tree is None or not math.isfinite(fov.r_max):
            return self.items + self._added
        radius = (fov.r_max + self._moved) * (1.0 + _WIDEN) + _SLACK_M
        rows = self._tree.query_ball_point([sensor_pv[0], sensor_pv[2]], radius)
        rows.sort()
        added = self._added
        if added:
            A = self._added_xy[: len(added)]
            far = np.hypot(A[:, 0] - sensor_pv[0], A[:, 1] - sensor_pv[2]) > radius  # NaN: not
            added = [item for item, out in zip(added, far.tolist(), strict=True) if not out]
        return [self.items[k] for k in rows] + added


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
