"""Tests of an oversize JPDA cluster (filters.jpda_prune, jpda_net's bounds; the tracker's
``tracker.tracks.oversize_cluster``: test_tracker): the error names the limit; pruning drops
only the weakest pairs, counts them and gives the exact JPDA of the pruned gate; a cluster
whose net fits is the same to the bit either way."""

from __future__ import annotations

import numpy as np
import pytest

from activetrack.filters.jpda import NetOversize, Pruning, jpda_probabilities
from activetrack.filters.jpda_net import (
    gate_clusters,
    net_edges_lower,
    net_edges_upper,
    net_marginals,
    track_order,
)

PD, PG = 0.9, 0.99


def band(rng, T, width):
    """Track t gates measurements t..t + width - 1, distinct ratios: a chain cluster."""
    L = np.zeros((T, T + width - 1))
    for t in range(T):
        L[t, t : t + width] = rng.exponential(1.0, width)
    return L


def net_edges(log_w):
    """The edges of the cluster's net: the least max_edges it builds under."""
    lo, hi = 0, 1
    while _raises(log_w, hi):
        lo, hi = hi, 2 * hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if _raises(log_w, mid) else (lo, mid)
    return hi


def _raises(log_w, max_edges):
    try:
        net_marginals(log_w, max_edges=max_edges)
    except NetOversize:
        return True
    return False


def log_weights(L, miss=1.0 - PD * PG):
    with np.errstate(divide="ignore"):
        return np.log(np.column_stack((np.full(L.shape[0], miss), L)))


def test_edge_bounds_hold_on_random_gates_and_order_is_the_dense_greedy():
    rng = np.random.default_rng(31)
    for _ in range(150):
        T, m = int(rng.integers(2, 9)), int(rng.integers(2, 10))
        gated = rng.random((T, m)) < rng.uniform(0.15, 0.6)
        order = track_order(gated)
        np.testing.assert_array_equal(order, dense_greedy_order(gated))
        edges = net_edges(log_weights(np.where(gated, 1.0, 0.0)))
        assert net_edges_lower(gated, order) <= edges <= net_edges_upper(gated, order)
    # a chain: the upper bound close to the true size (38 edges)
    gated = band(rng, 8, 2) > 0
    order = track_order(gated)
    edges = net_edges(log_weights(np.where(gated, 1.0, 0.0)))
    assert (net_edges_lower(gated, order), edges, net_edges_upper(gated, order)) == (8, 38, 45)


def dense_greedy_order(gated):
    """The greedy order as first written: the cut's growth of every track each step."""
    G = gated.astype(np.int64)
    remaining, in_cut = G.sum(axis=0), np.zeros(gated.shape[1], dtype=bool)
    left, order = np.ones(len(G), dtype=bool), []
    for _ in range(len(G)):
        enters = (~in_cut & (remaining >= 2)).astype(np.int64)
        leaves = (in_cut & (remaining == 1)).astype(np.int64)
        growth = np.where(left, G @ (enters - leaves), np.iinfo(np.int64).max)
        t = int(np.argmin(growth))
        order.append(t)
        left[t] = False
        remaining -= G[t]
        in_cut = (in_cut | gated[t]) & (remaining > 0)
    return order


def test_an_oversize_cluster_raises_or_is_pruned_to_the_exact_jpda_of_its_weakest_pairs_gone():
    rng = np.random.default_rng(7)
    L = band(rng, 10, 4)  # 5^10 events: on the net, 244 edges
    assert net_edges(log_weights(L)) == 244
    with pytest.raises(NetOversize, match="max_edges=40 ") as raised:
        jpda_probabilities(L, PD, PG, max_edges=40)
    assert (raised.value.tracks, raised.value.pairs) == (10, 40)
    pruning = Pruning()
    beta = jpda_probabilities(L, PD, PG, max_edges=40, oversize="prune", pruning=pruning)
    dropped = (L > 0) & (beta[:, 1:] == 0.0)
    assert (pruning.clusters, pruning.pairs, int(dropped.sum())) == (1, 20, 20)
    kept = (L > 0) & ~dropped
    assert L[dropped].max() < L[kept].min()  # only the weakest pairs go
    pruned = np.where(kept, L, 0.0)
    np.testing.assert_array_equal(beta, jpda_probabilities(pruned, PD, PG, max_edges=40))
    for tracks, cols in gate_clusters(kept):  # every part fits now
        net_marginals(log_weights(pruned[np.ix_(tracks, cols)]), max_edges=40)
    # one pair fewer dropped (the strongest of them back) would not provably fit
    t, j = np.argwhere(dropped & (L == L[dropped].max()))[0]
    back = kept.copy()
    back[t, j] = True
    part = next(p for p in gate_clusters(back) if t in p[0])
    block = back[np.ix_(*part)]
    assert net_edges_upper(block, track_order(block)) > 40


def test_a_cluster_whose_net_fits_is_the_same_to_the_bit_when_pruning_is_allowed():
    rng = np.random.default_rng(8)
    for T in (7, 12, 40):
        L = band(rng, T, 3) * (rng.random((T, T + 2)) < 0.9)
        pruning = Pruning()
        exact = jpda_probabilities(L, PD, PG)
        np.testing.assert_array_equal(
            jpda_probabilities(L, PD, PG, oversize="prune", pruning=pruning), exact
        )
        assert (pruning.clusters, pruning.pairs) == (0, 0)
    with pytest.raises(ValueError, match="oversize: must be one of"):
        jpda_probabilities(L, PD, PG, oversize="approximate")  # type: ignore[arg-type]
