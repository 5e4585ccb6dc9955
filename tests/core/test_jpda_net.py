"""Tests of the exact JPDA marginals on the hypothesis net (filters.jpda_net, through
filters.jpda.jpda_probabilities): against enumeration of the joint events, against closed forms,
against an independent dynamic programme over measurement subsets, and at sizes enumeration
cannot reach."""

from __future__ import annotations

import math

import numpy as np
import pytest

from activetrack.filters import jpda, jpda_net
from activetrack.filters.jpda import (
    _feasible_events,
    gate_probability,
    jpda_probabilities,
    jpda_probabilities_enumerated,
    jpda_update,
    likelihood_ratios,
    predict_measurements,
)
from activetrack.filters.jpda_net import gate_clusters, net_marginals, track_order
from activetrack.models.motion import NearlyConstantVelocity
from activetrack.models.sensors import RangeBearingSensor

ORIGIN = np.zeros(4)


@pytest.fixture(params=["net", "net-by-columns", "default"])
def engine(request, monkeypatch):
    """Every cluster on the net ("net"; "net-by-columns": its free options found a column at
    a time, as for a big net), or small clusters enumerated as by default."""
    if request.param != "default":
        monkeypatch.setattr(jpda, "ENUMERATION_EVENTS", 0)
    if request.param == "net-by-columns":
        monkeypatch.setattr(jpda_net, "_BROADCAST_CELLS", 0)
    return request.param


def assert_marginals(beta, L):
    """Rows sum to 1, each measurement's column to at most 1, ungated pairs get nothing."""
    np.testing.assert_allclose(beta.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    assert np.all(beta[:, 1:].sum(axis=0) <= 1.0 + 1e-12)
    assert np.all((beta >= 0.0) & (beta <= 1.0))
    assert np.all(beta[:, 1:][L == 0.0] == 0.0)


def subset_dp_betas(L, miss):
    """Independent reference: forward sums over the full set of used measurements (bit masks,
    no clustering, no track order, no pruning), one pass per (track, option) with that
    track's row restricted to the option. Small m only (2^m states)."""
    T, m = L.shape
    W = np.column_stack((miss, L))

    def total(W):
        f = np.zeros(2**m)
        f[0] = 1.0
        states = np.arange(2**m)
        for t in range(T):
            g = W[t, 0] * f
            for j in range(m):
                free = (states >> j) & 1 == 0
                np.add.at(g, states[free] | (1 << j), W[t, j + 1] * f[free])
            f = g
        return f.sum()

    Z = total(W)
    beta = np.zeros((T, m + 1))
    for t in range(T):
        for j in range(m + 1):
            Wt = W.copy()
            Wt[t] = 0.0
            Wt[t, j] = W[t, j]
            beta[t, j] = total(Wt) / Z
    return beta


# --- equal to enumeration --------------------------------------------------------------------


def test_net_equals_enumeration_on_random_gates(engine):
    rng = np.random.default_rng(11)
    for _ in range(400):
        T = int(rng.integers(1, 7))
        m = int(rng.integers(0, 8))
        density = rng.uniform(0.1, 1.0)
        L = rng.exponential(2.0, size=(T, m)) * (rng.random((T, m)) < density)
        if T > 1 and rng.random() < 0.3:
            L[rng.integers(T)] = 0.0  # a track with an empty gate
        if m > 1 and rng.random() < 0.3:
            L[:, rng.integers(m)] = 0.0  # a measurement no track gates
        pd, pg = rng.uniform(0.3, 1.0, T), float(rng.uniform(0.8, 1.0))
        beta = jpda_probabilities(L, pd, pg)
        np.testing.assert_allclose(
            beta, jpda_probabilities_enumerated(L, pd, pg, max_events=10**6), rtol=0, atol=1e-12
        )
        assert_marginals(beta, L)


def test_net_equals_enumeration_over_a_wide_dynamic_range(engine):
    # Ratios over 400 e-folds: the net's forward and backward sums are in log space.
    rng = np.random.default_rng(12)
    for _ in range(100):
        T, m = int(rng.integers(2, 7)), int(rng.integers(1, 7))
        L = np.exp(rng.uniform(-200, 200, (T, m))) * (rng.random((T, m)) < 0.8)
        beta = jpda_probabilities(L, 0.95, 0.999)
        np.testing.assert_allclose(
            beta, jpda_probabilities_enumerated(L, 0.95, 0.999), rtol=0, atol=1e-12
        )
        assert_marginals(beta, L)


def test_one_track_is_the_pdaf_closed_form(engine):
    L = np.array([[0.5, 0.0, 2.0, 1e-3]])
    pd, pg = 0.9, gate_probability(9.0, 2)
    q = 1.0 - pd * pg
    expected = np.concatenate(([q], L[0])) / (q + L.sum())
    np.testing.assert_allclose(jpda_probabilities(L, pd, pg)[0], expected, rtol=0, atol=1e-15)


def test_tracks_sharing_nothing_each_get_the_pdaf_closed_form():
    rng = np.random.default_rng(17)
    T, k = 12, 40
    L = np.zeros((T, T * k))
    for t in range(T):  # disjoint gates of 0..39 measurements
        n = int(rng.integers(0, k))
        L[t, t * k : t * k + n] = rng.exponential(1.0, n)
    pd = rng.uniform(0.5, 0.99, T)
    beta = jpda_probabilities(L, pd, 0.99)
    q = 1.0 - 0.99 * pd
    expected = np.column_stack((q, L)) / (q + L.sum(axis=1))[:, None]
    np.testing.assert_allclose(beta, expected, rtol=1e-14, atol=0)


def test_all_gated_dense_equal_ratios_matches_the_counting_formula():
    # T tracks, m measurements, every pair gated with ratio l, miss weight q:
    # c(T, m) = sum_k C(T, k) m!/(m - k)! l^k q^(T - k) (events with k assignments), and by
    # symmetry beta_0 = q c(T-1, m) / c(T, m), beta_j = l c(T-1, m-1) / c(T, m).
    T, m, l, pd, pg = 8, 10, 0.7, 0.9, 0.99
    q = 1.0 - pd * pg

    def c(T, m):
        return sum(math.comb(T, k) * math.perm(m, k) * l**k * q ** (T - k) for k in range(T + 1))

    beta = jpda_probabilities(np.full((T, m), l), pd, pg)
    np.testing.assert_allclose(beta[:, 0], q * c(T - 1, m) / c(T, m), rtol=1e-13)
    np.testing.assert_allclose(beta[:, 1:], l * c(T - 1, m - 1) / c(T, m), rtol=1e-13)
    assert_marginals(beta, np.full((T, m), l))


def test_all_gated_dense_random_ratios_match_a_subset_dp():
    # 12,975,561 feasible events: too many to enumerate in a test; the DP over the 2^10 sets
    # of used measurements is exact and shares nothing with the net but the event weights.
    rng = np.random.default_rng(13)
    L = rng.exponential(1.0, size=(8, 10))
    pd = rng.uniform(0.6, 0.95, 8)
    beta = jpda_probabilities(L, pd, 0.99)
    np.testing.assert_allclose(beta, subset_dp_betas(L, 1.0 - pd * 0.99), rtol=0, atol=1e-12)
    assert_marginals(beta, L)


def crowded_scene(seed, n_targets=10, n_clutter=6):
    """Ratios and gate of ``n_targets`` in a tight cluster 3 km from a range-bearing radar
    (Pd 0.9), predicted with 20 m position uncertainty, with Poisson clutter near them."""
    rng = np.random.default_rng(seed)
    sensor = RangeBearingSensor(sigma_r=5.0, sigma_b=0.002, pd=0.9)
    model = NearlyConstantVelocity(q=1.0)
    truth = np.column_stack(
        [
            3000.0 + rng.uniform(-50, 50, n_targets),
            np.zeros(n_targets),
            rng.uniform(-50, 50, n_targets),
            np.zeros(n_targets),
        ]
    )
    P = np.broadcast_to(np.diag([100.0, 4.0, 100.0, 4.0]), (n_targets, 4, 4))
    X = truth + rng.normal(0.0, 10.0, size=truth.shape) * np.array([1.0, 0.0, 1.0, 0.0])
    detected = rng.random(n_targets) < sensor.pd
    Z = sensor.sample(truth[detected], ORIGIN, rng)
    n_c = rng.poisson(n_clutter)
    box = (2940.0, 3060.0, -0.02, 0.02)  # range (m), bearing (rad)
    clutter = np.column_stack([rng.uniform(*box[:2], n_c), rng.uniform(*box[2:], n_c)])
    Z = np.vstack([Z, clutter])
    lam = n_clutter / ((box[1] - box[0]) * (box[3] - box[2]))
    zhat, _, S = predict_measurements(X, P, sensor, ORIGIN, model)
    nu = np.asarray(sensor.residual(Z[None], zhat[:, None]))
    L, _ = likelihood_ratios(nu, S, sensor.pd, lam, 16.0)
    return L, gate_probability(16.0, 2)


def test_crowded_ten_targets_equal_enumeration_beyond_the_old_event_cap():
    L, pg = crowded_scene(seed=6, n_clutter=4)
    # The tracker used to split a cluster into PDAs past 200,000 events by the product bound
    # (233,280 in the crowded scene); here 2,250,000 by that bound, 251,544 feasible.
    assert np.prod(1 + (L > 0.0).sum(axis=1)) == 2_250_000
    assert _feasible_events(L > 0.0, 10**6).shape[0] == 251_544
    beta = jpda_probabilities(L, 0.9, pg)
    reference = jpda_probabilities_enumerated(L, 0.9, pg, max_events=10**6)
    np.testing.assert_allclose(beta, reference, rtol=0, atol=1e-12)
    assert_marginals(beta, L)


# --- clusters, order, limits -----------------------------------------------------------------


def test_clusters_are_the_connected_components_of_the_gate():
    gated = np.array(
        [
            [1, 0, 0, 0, 0],
            [1, 1, 0, 0, 0],
            [0, 0, 0, 0, 0],
            [0, 0, 0, 1, 0],
            [0, 1, 0, 0, 0],
        ],
        dtype=bool,
    )
    clusters = [(list(t), list(m)) for t, m in gate_clusters(gated)]
    assert clusters == [([0, 1, 4], [0, 1]), ([2], []), ([3], [3])]


def test_clusters_by_union_find_and_by_label_propagation_agree(monkeypatch):
    rng = np.random.default_rng(16)
    gated = rng.random((400, 600)) < 0.003
    small = gate_clusters(gated)
    monkeypatch.setattr(jpda_net, "_UNION_FIND_PAIRS", 0)
    large = gate_clusters(gated)
    assert len(small) == len(large) > 50
    for (t1, m1), (t2, m2) in zip(small, large, strict=True):
        np.testing.assert_array_equal(t1, t2)
        np.testing.assert_array_equal(m1, m2)
    for tracks, meas in small:  # a partition, closed under the gate
        assert not gated[np.ix_(tracks, np.setdiff1d(np.arange(600), meas))].any()


def chain_betas(L, miss):
    """Independent reference for a chain (track t gates measurements t and t + 1 only):
    forward-backward over the state "track t took measurement t + 1", scaled per step."""
    T = L.shape[0]
    q, a, b = miss, L[np.arange(T), np.arange(T)], L[np.arange(T), np.arange(T) + 1]
    # Transfer of track t from state s (measurement t taken) to s': rows s, cols s'.
    M = np.zeros((T, 2, 2))
    M[:, 0, 0], M[:, 1, 0] = q + a, q
    M[:, 0, 1], M[:, 1, 1] = b, b
    f = np.zeros((T + 1, 2))
    f[0] = [1.0, 0.0]
    for t in range(T):
        f[t + 1] = f[t] @ M[t]
        f[t + 1] /= f[t + 1].sum()
    g = np.ones((T + 1, 2))
    for t in range(T - 1, -1, -1):
        g[t] = M[t] @ g[t + 1]
        g[t] /= g[t].sum()
    beta = np.zeros((T, 3))  # miss, measurement t, measurement t + 1
    for t in range(T):
        beta[t, 0] = q[t] * (f[t] @ np.array([1.0, 1.0])) * g[t + 1, 0]
        beta[t, 1] = a[t] * f[t, 0] * g[t + 1, 0]
        beta[t, 2] = b[t] * f[t].sum() * g[t + 1, 1]
        beta[t] /= beta[t].sum()
    return beta


def test_chain_order_keeps_the_cut_small_and_the_net_linear():
    # 300 tracks in a chain, track t gating measurements t and t + 1, given shuffled: the
    # greedy order walks the chain (a cut of one measurement), so the net has at most ~3 edges
    # per track; enumeration would face more than 2^300 events.
    rng = np.random.default_rng(14)
    T = 300
    chain = np.zeros((T, T + 1))
    chain[np.arange(T), np.arange(T)] = rng.exponential(1.0, T)
    chain[np.arange(T), np.arange(T) + 1] = rng.exponential(1.0, T)
    pd = rng.uniform(0.5, 0.95, T)
    perm = rng.permutation(T)
    beta = jpda_probabilities(chain[perm], pd[perm], 0.99, max_edges=5 * T)
    assert_marginals(beta, chain[perm])
    expected = chain_betas(chain, 1.0 - 0.99 * pd)
    got = beta[np.argsort(perm)]
    np.testing.assert_allclose(got[:, 0], expected[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        got[np.arange(T), np.arange(T) + 1], expected[:, 1], rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(
        got[np.arange(T), np.arange(T) + 2], expected[:, 2], rtol=0, atol=1e-12
    )
    order = track_order(chain[perm] > 0.0)
    assert sorted(order) == list(range(T))


def test_the_memory_limit_is_named_and_no_event_is_an_error(engine):
    with pytest.raises(ValueError, match="max_edges=50 "):
        jpda_probabilities(np.ones((6, 8)), 0.9, 0.99, max_edges=50)
    with pytest.raises(ValueError, match="max_edges"):
        jpda_probabilities(np.ones((2, 2)), 0.9, 0.99, max_edges=0)
    # Pd Pg = 1: every track must take a measurement.
    with pytest.raises(ValueError, match="no feasible joint event"):
        jpda_probabilities(np.array([[0.0, 0.0]]), 1.0, 1.0)  # nothing in its gate
    with pytest.raises(ValueError, match="no feasible joint event"):
        jpda_probabilities(np.array([[1.0], [2.0]]), 1.0, 1.0)  # two tracks, one measurement
    with pytest.raises(ValueError, match="no feasible joint event"):
        net_marginals(np.array([[-np.inf, 0.0], [-np.inf, 0.5]]))
    # ... and where it can, the marginals are the enumeration's.
    L = np.array([[1.0, 3.0, 0.0], [2.0, 0.5, 4.0]])
    beta = jpda_probabilities(L, 1.0, 1.0)
    np.testing.assert_allclose(beta, jpda_probabilities_enumerated(L, 1.0, 1.0), atol=1e-15)
    np.testing.assert_array_equal(beta[:, 0], 0.0)


# --- the update at sizes enumeration cannot do -----------------------------------------------


def spread_scene(rng, n_targets, n_clutter):
    """``n_targets`` spread 100-200 m apart and Poisson clutter over the surveillance area of
    a range-bearing radar; predicted tracks near the truth."""
    sensor = RangeBearingSensor(sigma_r=10.0, sigma_b=0.005, pd=0.9)
    model = NearlyConstantVelocity(q=1.0)
    grid = np.stack(np.meshgrid(np.arange(6), np.arange(5)), -1).reshape(-1, 2)[:n_targets]
    truth = np.zeros((n_targets, 4))
    truth[:, 0] = 3000.0 + 150.0 * grid[:, 0]
    truth[:, 2] = -300.0 + 150.0 * grid[:, 1]
    means = truth + rng.normal(0.0, 10.0, truth.shape) * np.array([1.0, 0.0, 1.0, 0.0])
    covs = np.broadcast_to(np.diag([100.0, 4.0, 100.0, 4.0]), (n_targets, 4, 4)).copy()
    box = (2800.0, 4000.0, -0.2, 0.2)
    Z = sensor.sample(truth[rng.random(n_targets) < sensor.pd], ORIGIN, rng)
    n_c = rng.poisson(n_clutter)
    clutter = np.column_stack([rng.uniform(*box[:2], n_c), rng.uniform(*box[2:], n_c)])
    lam = n_clutter / ((box[1] - box[0]) * (box[3] - box[2]))
    return sensor, model, means, covs, np.vstack([Z, clutter]), lam


@pytest.mark.parametrize(("n_targets", "n_clutter", "largest"), [(30, 20, 1), (30, 1000, 2)])
def test_jpda_update_clusters_spread_targets_and_heavy_clutter(
    n_targets, n_clutter, largest, engine
):
    rng = np.random.default_rng(15)
    sensor, model, means, covs, Z, lam = spread_scene(rng, n_targets, n_clutter)
    res = jpda_update(means, covs, Z, sensor, ORIGIN, model, clutter_density=lam, gamma=16.0)
    pg = gate_probability(16.0, 2)
    with pytest.raises(ValueError, match="max_events"):  # what jpda_update used to do
        jpda_probabilities_enumerated(res.likelihood_ratios, sensor.pd, pg)
    # Per cluster the enumeration is within reach, and equal.
    clusters = gate_clusters(res.gated)
    assert max(tracks.size for tracks, _ in clusters) == largest
    for tracks, meas in clusters:
        sub = res.likelihood_ratios[np.ix_(tracks, meas)]
        expected = jpda_probabilities_enumerated(sub, sensor.pd, pg)
        np.testing.assert_allclose(
            res.beta[np.ix_(tracks, np.concatenate(([0], meas + 1)))], expected, atol=1e-12
        )
    assert_marginals(res.beta, res.likelihood_ratios)
    assert np.all(np.linalg.eigvalsh(res.covs) > 0.0)
