"""The tracker's spatial indexes give supersets of what the exact tests accept, so the
tracker's decisions are the all-pairs ones (activetrack.tracking.spatial)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from activetrack.models.fov import FieldOfView
from activetrack.tracking.management import coalesce_d2
from activetrack.tracking.spatial import FovIndex, close_pairs, largest_xy_eigenvalue


def _covs(rng, n):
    """Random SPD pv covariances ``(n, 4, 4)`` with xy blocks from 1 to 1e4 m^2, anisotropic."""
    A = rng.standard_normal((n, 4, 4)) * rng.uniform(1.0, 100.0, (n, 1, 1))
    return A @ np.swapaxes(A, 1, 2) + np.eye(4)


def test_largest_xy_eigenvalue_equals_eigvalsh():
    covs = _covs(np.random.default_rng(1), 50)
    exact = np.linalg.eigvalsh(covs[:, [0, 2]][:, :, [0, 2]])[:, -1]
    np.testing.assert_allclose(largest_xy_eigenvalue(covs), exact, rtol=1e-12)


def test_close_pairs_holds_every_pair_the_mahalanobis_test_accepts():
    rng = np.random.default_rng(2)
    n = 300  # above the brute-force size: the k-d tree answers
    xy = rng.uniform(0.0, 3000.0, (n, 2))  # crowded: many pairs within reach
    covs = _covs(rng, n)
    P = covs[:, [0, 2]][:, :, [0, 2]]
    found = set(close_pairs(xy, coalesce_d2(4) * largest_xy_eigenvalue(covs)))
    close = set()
    for i in range(n):
        dp = xy[i] - xy[i + 1 :]
        d2 = np.einsum("kd,kd->k", dp, np.linalg.solve(P[i] + P[i + 1 :], dp[..., None])[..., 0])
        close |= {(i, i + 1 + k) for k in np.flatnonzero(d2 <= coalesce_d2(4))}
    assert len(close) > 50
    assert close <= found
    assert len(found) < n * (n - 1) // 4  # and it is not all the pairs
    assert all(i < j for i, j in found)


def test_fov_index_candidates_hold_every_track_in_view_after_moves_and_starts():
    rng = np.random.default_rng(3)
    n = 500
    pv = np.column_stack(
        [rng.uniform(0, 50_000, n), np.zeros(n), rng.uniform(0, 50_000, n), np.zeros(n)]
    )
    items = [f"t{k}" for k in range(n)]
    index = FovIndex(items, pv[:, [0, 2]])
    fov = FieldOfView(0.3, math.pi / 2, 100.0, 7_000.0)
    sensors = rng.uniform(0, 50_000, (20, 2))
    for s_xy in sensors:
        s = np.array([s_xy[0], 0.0, s_xy[1], 0.0])
        got = index.candidates(fov, s)
        inside = {items[k] for k in np.flatnonzero(fov.contains(pv, s))}
        assert inside <= set(got) and len(got) < n // 4
        assert got == sorted(got, key=lambda name: int(name[1:]))  # in the given order
    # a track moved 900 m by an update is still found; a new track is always a candidate
    k = int(np.argmin(np.hypot(pv[:, 0] - 25_000.0, pv[:, 2] - 25_000.0)))
    s = np.array([pv[k, 0] + 7_000.0 + 850.0, 0.0, pv[k, 2], 0.0])
    all_around = FieldOfView(0.0, 2.0 * math.pi, 0.0, 7_000.0)
    assert items[k] not in index.candidates(all_around, s)
    index.moved(items[k], pv[k, [0, 2]] + [900.0, 0.0])
    assert items[k] in index.candidates(all_around, s)
    index.add("new")
    assert index.candidates(all_around, np.array([-1e6, 0.0, -1e6, 0.0]))[-1] == "new"
    # a track added at its position is a candidate of the scans within reach of it only, and
    # its moves widen the radius as an indexed track's do
    far = np.array([-1e6, 0.0, -1e6, 0.0])
    index.add("placed", np.array([-1e6 + 7_890.0, -1e6]))  # radius now 7,000 + 900 m
    assert index.candidates(all_around, far)[-2:] == ["new", "placed"]
    assert "placed" not in index.candidates(all_around, np.array([-1e6 - 60.0, 0.0, -1e6, 0.0]))
    index.moved("placed", np.array([-1e6 + 7_890.0 + 1_000.0, -1e6]))  # radius 8,000 m
    assert "placed" in index.candidates(all_around, np.array([-1e6 - 60.0, 0.0, -1e6, 0.0]))
    assert "placed" not in index.candidates(all_around, s)
    # many moves at once (an unknown item ignored) widen the radius as the moves one by one
    one, many = FovIndex(items, pv[:, [0, 2]]), FovIndex(items, pv[:, [0, 2]])
    one.add("placed", pv[0, [0, 2]])
    many.add("placed", pv[0, [0, 2]])
    moved = [items[3], items[7], "placed", items[11]]
    xy = rng.normal(0.0, 500.0, (4, 2)) + pv[[3, 7, 0, 11]][:, [0, 2]]
    for item, p in zip(moved, xy, strict=True):
        one.moved(item, p)
    many.moved_many(moved, xy)
    assert many._moved == pytest.approx(one._moved, rel=1e-15) and many._moved > 0.0
    many.moved_many([], np.zeros((0, 2)))
    # an unbounded range: every track
    assert len(index.candidates(FieldOfView(), s)) == n + 2
    # many starts (past the buffer's first 16 rows, some without a position): the placed ones
    # within reach are candidates, the far ones not, the unplaced ones always, in their order
    starts = rng.uniform(-1e6 - 20_000.0, -1e6 + 20_000.0, (40, 2))
    for k, p in enumerate(starts):
        index.add(f"s{k}", None if k % 9 == 0 else p)
    reach = 7_000.0 + 1_000.0  # the radius after the moves above (widened by ~1e-9 relative)
    near = np.hypot(starts[:, 0] + 1e6, starts[:, 1] + 1e6) <= reach
    got = index.candidates(all_around, far)
    want = ["new", "placed"] + [f"s{k}" for k in range(40) if k % 9 == 0 or near[k]]
    assert got == want and 5 < len(want) < 30
