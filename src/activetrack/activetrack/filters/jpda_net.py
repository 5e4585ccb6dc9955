"""Exact JPDA marginals without enumerating joint events: efficient hypothesis management.

The JPDA marginals (module :mod:`activetrack.filters.jpda`; Bar-Shalom, Daum & Huang 2009,
eq. 40-41) are sums over feasible joint events ``theta`` of

    P(theta | Z) = (1/c) prod_t w[t, theta_t],   w[t, 0] = 1 - Pd_t Pg_t,   w[t, j] = l[t, j]

whose number grows exponentially with the tracks that share measurements.  Efficient
hypothesis management (EHM: Maskell, Briers & Wright, "Fast mutual exclusion", Proc. SPIE 5428,
2004; Horridge & Maskell, "Real-time tracking of hundreds of targets with efficient exact JPDAF
implementation", FUSION 2006) computes the same sums exactly on a layered net:

- Tracks are taken in an order ``t_1..t_T``; ``A_k`` is the set of measurements gated by some
  track after ``t_k`` (still *accessible* to later tracks).
- A node of layer ``k`` is a set ``U`` of measurements, namely those used by ``t_1..t_k`` that
  are in ``A_k``: the only part of a partial event the later tracks can see.  Layer 0 and
  layer ``T`` hold one node, the empty set.
- From node ``U`` of layer ``k - 1``, track ``t_k`` takes option ``j`` (0 = no measurement, or a
  gated measurement not in ``U``) with weight ``w[t_k, j]``, to node ``(U + {j}) & A_k``.

Every feasible event is one path from the root to the leaf, and the product of its edge weights
is the event's weight, so with the forward weight ``f(U)`` (sum over paths from the root) and
the backward weight ``b(U)`` (sum over paths to the leaf)::

    c = f(leaf) = b(root)
    beta[t_k, j] = (1/c) sum_{edges U -j-> U' of layer k} f(U) w[t_k, j] b(U')

The net's size depends on how many measurements are shared across the order's cut at each
layer, not on the number of events: tracks are first split into clusters (connected components
of the gate, which are independent), then each cluster's tracks are ordered greedily so the
set ``A_k & (gates of t_1..t_k)`` stays small.  All weights are carried in log space (no under-
or overflow at any cluster size).  The only limit is memory: ``max_edges`` edges per cluster's
net, :class:`NetOversize` (a ValueError naming it) beyond.

Bounds on a net's edges without building it (:func:`net_edges_upper`, :func:`net_edges_lower`),
from the order's cuts ``C_k = (gates of t_1..t_k) & A_k``: a node of layer ``k`` is a subset of
``C_k``, fixed by what each placed track took of ``C_k`` (nothing, or one of its
``n_i = |gate_i & C_k|``), so

    nodes_k <= min(2^|C_k|, prod_{i <= k} (1 + n_i)),   edges_k <= nodes_{k-1} (1 + |gate_{t_k}|)

and, when every track can miss, placed tracks whose ``gate_i & C_k`` are pairwise disjoint
choose independently while the others take nothing: ``nodes_k >= prod_{i in D} (1 + n_i)``
for any such set ``D`` (a greedy one), and each node has an edge into it.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from activetrack.arraytypes import BoolArray, FloatArray

__all__ = [
    "DEFAULT_MAX_EDGES",
    "GateClusters",
    "NetOversize",
    "events_bound",
    "gate_clusters",
    "net_edges_lower",
    "net_edges_upper",
    "net_marginals",
    "track_order",
]

# About 50 bytes and 0.3-1 us per edge (numpy 2.4, loaded 2-core VM: 1.95 M edges, 99 MB peak,
# 1.8 s): the default bounds one cluster's net near 250 MB.
DEFAULT_MAX_EDGES = 5_000_000
_BROADCAST_CELLS = 1 << 20  # _free: above this many (node, option, word) cells, by columns
_UNION_FIND_PAIRS = 500  # gate_clusters: above this many gated pairs, vectorised propagation
_LOWER_BOUND_LAYERS = 8  # net_edges_lower: the layers of largest upper bound given a lower one

IntArray = npt.NDArray[np.intp]

_NO_EVENT = (
    "jpda_probabilities: no feasible joint event has positive probability "
    "(a track with Pd * Pg = 1 has no measurement in its gate)"
)


class NetOversize(ValueError):
    """A cluster's hypothesis net would hold more than ``max_edges`` edges: its ``tracks``,
    ``measurements`` and gated ``pairs``, for a caller that names its own way out."""

    def __init__(self, message: str, *, tracks: int, measurements: int, pairs: int, max_edges: int):
        super().__init__(message)
        self.tracks = tracks
        self.measurements = measurements
        self.pairs = pairs
        self.max_edges = max_edges


def gate_clusters(gated: BoolArray) -> list[tuple[IntArray, IntArray]]:
    """Connected components of the gate ``(T, m)``: ``(tracks, measurements)`` index arrays, one
    pair per cluster of tracks linked through shared gated measurements (a track with nothing
    in its gate is a cluster of its own with no measurements), in order of their first track.
    Clusters are independent: the JPDA marginals of a track depend only on its cluster."""
    T, m = gated.shape
    if T == 0:
        return []
    rows, cols = np.nonzero(gated)
    label = _component_labels(T, m, rows, cols)  # each track's component's first track
    by_track = np.argsort(label, kind="stable")
    cuts = np.flatnonzero(np.diff(label[by_track])) + 1
    first = by_track[np.concatenate(([0], cuts))]
    measurement_label = np.full(m, -1, dtype=np.intp)
    measurement_label[cols] = label[rows]
    used = np.flatnonzero(measurement_label >= 0)
    by_measurement = used[np.argsort(measurement_label[used], kind="stable")]
    sorted_label = measurement_label[by_measurement]
    lo = np.searchsorted(sorted_label, first, side="left").tolist()
    hi = np.searchsorted(sorted_label, first, side="right").tolist()
    bounds = [0, *cuts.tolist(), T]  # np.split's pieces, sliced directly (it costs ~5 us each)
    return [
        (by_track[bounds[k] : bounds[k + 1]], by_measurement[a:b])
        for k, (a, b) in enumerate(zip(lo, hi, strict=True))
    ]


class GateClusters:
    """A gate ``gated`` ``(T, m)`` and its :func:`gate_clusters` (``clusters``), computed once
    here: a caller that needs them and the marginals too (the tracker's updates go by the gate's
    clusters) passes this to :func:`~activetrack.filters.jpda.jpda_probabilities`, which then
    does not cluster again. The gate is held, not copied: it must not change afterwards."""

    __slots__ = ("clusters", "gated")

    def __init__(self, gated: BoolArray):
        self.gated = np.asarray(gated, dtype=bool)
        self.clusters = gate_clusters(self.gated)

    def split(self, positive: BoolArray) -> list[tuple[IntArray, IntArray]]:
        """:func:`gate_clusters` of ``positive`` ``(T, m)``, a part of the gate (the pairs of a
        positive likelihood ratio: a gated pair's ratio can underflow to 0), from the gate's
        clusters: the same list where ``positive`` is the gate, else each cluster that lost a
        pair is clustered again on its own block (the same tracks and measurements, in the same
        order, as clustering ``positive`` whole gives; the list's order may differ). ValueError
        if ``positive`` has a pair outside the gate."""
        if positive.shape != self.gated.shape:
            raise ValueError(
                f"clusters: a gate of shape {positive.shape} expected, got {self.gated.shape}"
            )
        if np.array_equal(positive, self.gated):
            return self.clusters
        if (positive & ~self.gated).any():
            raise ValueError("clusters: a pair of positive likelihood ratio lies outside the gate")
        lost = np.asarray((self.gated & ~positive).any(axis=1))  # tracks that lost a pair
        out: list[tuple[IntArray, IntArray]] = []
        for tracks, measurements in self.clusters:
            if not lost[tracks].any():
                out.append((tracks, measurements))
                continue
            for t, j in gate_clusters(positive[np.ix_(tracks, measurements)]):
                out.append((tracks[t], measurements[j]))
        return out


def _component_labels(T: int, m: int, rows: IntArray, cols: IntArray) -> IntArray:
    """``(T,)``: for each track the smallest track index of its component, from the gated
    pairs ``(rows[i], cols[i])``."""
    if rows.size <= _UNION_FIND_PAIRS:  # few pairs: union-find in Python costs least
        parent = list(range(T))

        def root(i: int) -> int:
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        first: dict[int, int] = {}  # measurement -> a track gating it
        for t, j in zip(rows.tolist(), cols.tolist(), strict=True):
            a, b = root(t), root(first.setdefault(j, t))
            if a != b:
                parent[max(a, b)] = min(a, b)
        return np.array([root(t) for t in range(T)], dtype=np.intp)
    # Many pairs: minimum-label propagation with hooking and pointer jumping, vectorised.
    # label[t] <= t is always a track of t's component; at the fixed point every track of a
    # component holds the same label, so the smallest index.
    label = np.arange(T, dtype=np.intp)
    while True:
        via = np.full(m, T, dtype=np.intp)
        np.minimum.at(via, cols, label[rows])  # smallest label among each measurement's tracks
        new = label.copy()
        np.minimum.at(new, rows, via[cols])
        np.minimum.at(new, label, new)  # hook: a track's old label takes its new one too
        while not np.array_equal(jumped := new[new], new):
            new = jumped
        if np.array_equal(new, label):
            return label
        label = new


def track_order(gated: BoolArray) -> IntArray:
    """A track order for the net of one cluster ``(T, m)``: greedy, each step the track that
    least grows the cut (measurements gated both by a placed track and by a track still to
    place), ties to the lower index.  Any order gives the same marginals; a small cut keeps
    the net small (a chain of overlapping gates gives a cut of one or two measurements).

    Placing ``t`` grows the cut by ``sum_{j in gate_t} v_j``, ``v_j = +1`` for a measurement
    outside the cut that another track still to place gates, ``-1`` for one in the cut that
    only ``t`` still gates; placing ``t`` changes ``v`` only on its own gate, so each track's
    growth is kept and changed there (``O(T^2 + pairs x tracks per measurement)``, not a
    product with the gate per step)."""
    G = np.asarray(gated, dtype=bool)
    T, m = G.shape
    rows, cols = np.nonzero(G)  # by track
    starts = np.searchsorted(rows, np.arange(T + 1))
    by_col = np.argsort(cols, kind="stable")
    col_tracks = rows[by_col]  # the tracks of each measurement, by measurement
    col_starts = np.searchsorted(cols[by_col], np.arange(m + 1))
    remaining = G.sum(axis=0).astype(np.int64)  # tracks still to place that gate each one
    in_cut = np.zeros(m, dtype=bool)

    def value(j: IntArray) -> npt.NDArray[np.int64]:
        r, c = remaining[j], in_cut[j]
        return (~c & (r >= 2)).astype(np.int64) - (c & (r == 1)).astype(np.int64)

    # exact small integers in float64 (inf: placed)
    growth = np.bincount(rows, weights=value(cols), minlength=T).astype(float)
    order = np.empty(T, dtype=np.intp)
    for k in range(T):
        t = int(np.argmin(growth))
        order[k] = t
        growth[t] = np.inf
        js = cols[starts[t] : starts[t + 1]]
        before = value(js)
        remaining[js] -= 1
        in_cut[js] = remaining[js] > 0
        change = value(js) - before
        for j, d in zip(js[change != 0].tolist(), change[change != 0].tolist(), strict=True):
            growth[col_tracks[col_starts[j] : col_starts[j + 1]]] += d
    return order


def events_bound(gated: BoolArray) -> float:
    """The product bound ``prod_t (1 + |gate_t|)`` on a cluster's feasible joint events, from
    its gate ``(T, m)`` (``inf`` past the float range, as a cluster of hundreds of tracks)."""
    with np.errstate(over="ignore"):
        return float(np.prod(1.0 + np.asarray(gated, dtype=bool).sum(axis=1)))


def net_edges_upper(gated: BoolArray, order: IntArray) -> float:
    """An upper bound on the edges of the net :func:`net_marginals` builds for one cluster's
    gate ``gated`` ``(T, m)`` in track ``order``, without building it (module docstring):
    ``O(T^2)`` on ``O(T m)`` data; a float (``inf`` past its range)."""
    log_nodes, size = _layer_log_nodes(np.asarray(gated, dtype=bool)[order])
    with np.errstate(over="ignore"):
        return float(np.exp(log_nodes[:-1]) @ (1.0 + size))


def net_edges_lower(gated: BoolArray, order: IntArray) -> float:
    """A lower bound on those edges when every track of the cluster may take no measurement
    (module docstring): the greedy disjoint tracks' product at the :data:`_LOWER_BOUND_LAYERS`
    layers of largest upper bound, at least one node per layer."""
    G = np.asarray(gated, dtype=bool)[order]
    log_nodes, _ = _layer_log_nodes(G)
    lower = float(G.shape[0])
    for k in np.argsort(-log_nodes[1:], kind="stable")[:_LOWER_BOUND_LAYERS].tolist():
        lower = max(lower, _disjoint_nodes(G[: k + 1], np.asarray(G[k + 1 :].any(axis=0))))
    return lower


def _layer_log_nodes(G: BoolArray) -> tuple[FloatArray, IntArray]:
    """For the gate ``G`` ``(T, m)`` in net order: the log of the upper bound on the nodes of
    layers 0..T, ``min(|C_k| log 2, sum_i log(1 + n_i))``, and each track's gate size."""
    T, m = G.shape
    remaining = G.sum(axis=0)  # tracks from position k on that gate each measurement
    placed = np.zeros(m, dtype=bool)
    in_cut = np.zeros(m, dtype=bool)
    per = np.zeros(T, dtype=np.int64)  # n_i = |gate_i & C_k| of the placed tracks
    log_nodes = np.zeros(T + 1)
    log2 = math.log(2.0)
    for k in range(T):
        remaining -= G[k]
        placed |= G[k]
        cut = placed & (remaining > 0)
        leaving = np.flatnonzero(in_cut & ~cut)  # all in gate k: no later track gates them
        if leaving.size and k:
            per[:k] -= G[:k, leaving].sum(axis=1)
        per[k] = int((G[k] & cut).sum())
        in_cut = cut
        log_nodes[k + 1] = min(int(cut.sum()) * log2, float(np.log1p(per[: k + 1]).sum()))
    return log_nodes, G.sum(axis=1)


def _disjoint_nodes(placed: BoolArray, accessible: BoolArray) -> float:
    """A lower bound on the nodes after the tracks ``placed`` ``(k, m)`` (in order) when the
    later tracks gate ``accessible`` ``(m,)``: ``prod (1 + n_i)`` over a greedy set of placed
    tracks whose parts of the cut are pairwise disjoint, the fewest first."""
    cut = placed.any(axis=0) & accessible
    parts = placed[:, cut]
    counts = parts.sum(axis=1)
    taken = np.zeros(parts.shape[1], dtype=bool)
    nodes = 1.0
    for i in np.argsort(counts, kind="stable").tolist():
        if counts[i] and not (parts[i] & taken).any():
            taken |= parts[i]
            nodes *= 1.0 + float(counts[i])
    return nodes


def _logsumexp_by(values: FloatArray, groups: IntArray, n: int) -> FloatArray:
    """``out[g] = log sum_{i: groups[i] = g} exp(values[i])`` for ``g < n`` (-inf if empty)."""
    top = np.full(n, -np.inf)
    np.maximum.at(top, groups, values)
    safe = np.where(np.isfinite(top), top, 0.0)
    total = np.bincount(groups, weights=np.exp(values - safe[groups]), minlength=n)
    with np.errstate(divide="ignore"):
        return np.asarray(np.log(total) + safe, dtype=float)


def _layer_sizes(layers: list[tuple[IntArray, IntArray, IntArray, int]]) -> list[int]:
    """Number of nodes of layers 1..T: each layer's sources are the previous layer's nodes."""
    return [n_src for *_, n_src in layers[1:]] + [1]


def _free(keys: npt.NDArray[np.uint64], bits: npt.NDArray[np.uint64]) -> BoolArray:
    """``(N, k)``: node ``i``'s used set ``keys[i]`` ``(words,)`` leaves option ``bits[o]``
    free (no bit in common; always for "no measurement", all bits zero)."""
    N, k = keys.shape[0], bits.shape[0]
    if N * k * keys.shape[1] <= _BROADCAST_CELLS:
        return np.asarray(~(keys[:, None, :] & bits[None, :, :]).any(axis=2), dtype=bool)
    free = np.empty((N, k), dtype=bool)  # a column at a time: no (N, k, words) temporary
    for o in range(k):
        free[:, o] = ~(keys & bits[o]).any(axis=1)
    return free


def _bit_masks(sets: BoolArray) -> npt.NDArray[np.uint64]:
    """Rows of ``sets`` ``(n, m)`` as bit masks ``(n, max(1, ceil(m / 64)))``: bit ``j % 64`` of
    word ``j // 64`` is column ``j``."""
    n, m = sets.shape
    words = max(1, (m + 63) // 64)
    padded = np.zeros((n, 64 * words), dtype=bool)
    padded[:, :m] = sets
    packed = np.packbits(padded, axis=1, bitorder="little")  # (n, 8 words) bytes
    return np.ascontiguousarray(packed).view("<u8").astype(np.uint64, copy=False)


def _node_ids(keys: npt.NDArray[np.uint64]) -> tuple[npt.NDArray[np.uint64], IntArray]:
    """Distinct rows of ``keys`` ``(E, words)`` and each row's index among them."""
    if keys.shape[1] == 1:
        unique, inverse = np.unique(keys[:, 0], return_inverse=True)
        return unique[:, None], inverse.ravel()
    rows = np.ascontiguousarray(keys).view(np.dtype((np.void, 8 * keys.shape[1]))).ravel()
    _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
    return keys[first], inverse.ravel()


def net_marginals(
    log_w: FloatArray, *, max_edges: int = DEFAULT_MAX_EDGES, order: IntArray | None = None
) -> FloatArray:
    """Exact marginals ``beta`` ``(T, m + 1)`` of one cluster from the log weights ``log_w``
    ``(T, m + 1)`` (column 0 no measurement, ``-inf`` for an ungated pair or an impossible
    miss), by the net of the module docstring built in :func:`track_order` (``order``: that
    order, when the caller has it).  The result's rows sum to 1 (``beta[t, j] = 0`` where
    ``log_w[t, j] = -inf``).

    Raises :class:`NetOversize` (a ValueError) when the net would hold more than
    ``max_edges`` edges, ValueError when no feasible event has positive weight.
    """
    T, m1 = log_w.shape
    m = m1 - 1
    allowed = np.isfinite(log_w)
    if T == 1:  # the PDAF's closed form, the one-layer net
        if not allowed[0].any():
            raise ValueError(_NO_EVENT)
        w = np.exp(log_w[0] - np.max(log_w[0]))
        return np.asarray(w / w.sum(), dtype=float)[None]
    order = track_order(allowed[:, 1:]) if order is None else order
    # Sets of measurements as bit masks, ``words`` uint64 each: row t of gate_bits is track
    # t's gate, bits[j] option j's measurement (none for j = 0).
    gate_bits = _bit_masks(allowed[:, 1:])
    words = gate_bits.shape[1]
    bits = np.vstack((np.zeros((1, words), dtype=np.uint64), _bit_masks(np.eye(m, dtype=bool))))
    # accessible[k]: measurements gated by the tracks placed after the k-th (k = 0..T-1).
    accessible = np.zeros((T, words), dtype=np.uint64)
    accessible[:-1] = np.bitwise_or.accumulate(gate_bits[order[:0:-1]], axis=0)[::-1]
    keys = np.zeros((1, words), dtype=np.uint64)
    layers: list[tuple[IntArray, IntArray, IntArray, int]] = []  # (src, option, dst, n_src)
    total_edges = 0
    for k, t in enumerate(order):
        options = np.flatnonzero(allowed[t])
        n_src = keys.shape[0]
        src, which = np.nonzero(_free(keys, bits[options]))  # node-option pairs allowed
        total_edges += src.size
        if total_edges > max_edges:
            pairs = int(allowed[:, 1:].sum())
            raise NetOversize(
                f"JPDA hypothesis net needs more than max_edges={max_edges} edges "
                f"(cluster of {T} tracks, {m} measurements, {pairs} gated pairs, {n_src} nodes "
                f"at track {k + 1} of {T}): tighten the gate or raise max_edges",
                tracks=T,
                measurements=m,
                pairs=pairs,
                max_edges=max_edges,
            )
        if src.size == 0:
            raise ValueError(_NO_EVENT)
        keys, dst = _node_ids((keys[src] | bits[options[which]]) & accessible[k])
        layers.append((src, options[which], dst, n_src))
    # keys: the last layer, one node (the empty set: nothing is accessible after the last track)
    forward: list[FloatArray] = [np.zeros(1)]  # log forward weights, layer by layer
    for (src, opt, dst, _), t, n_dst in zip(layers, order, _layer_sizes(layers), strict=True):
        forward.append(_logsumexp_by(forward[-1][src] + log_w[t, opt], dst, n_dst))
    if not np.isfinite(forward[-1][0]):
        raise ValueError(_NO_EVENT)
    beta = np.zeros((T, m1))
    backward: FloatArray = np.zeros(1)
    for k in range(T - 1, -1, -1):
        src, opt, dst, n_src = layers[k]
        t = order[k]
        edge = log_w[t, opt] + backward[dst]
        through = forward[k][src] + edge  # log of the weight of all events through the edge
        w = np.exp(through - np.max(through))
        beta[t] = np.bincount(opt, weights=w, minlength=m1) / w.sum()
        backward = _logsumexp_by(edge, src, n_src)
    return beta
