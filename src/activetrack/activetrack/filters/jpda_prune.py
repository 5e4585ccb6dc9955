"""An oversize JPDA cluster made to fit: its weakest gated pairs dropped, then the exact JPDA.

A cluster of the gate whose hypothesis net would exceed ``max_edges`` (the memory bound of
:mod:`activetrack.filters.jpda_net`; e.g. hundreds of tentative tracks started from 1,000
false alarms a scan, chained through shared detections) has no exact JPDA within that memory.
This is the named approximation ``oversize: prune`` of
:func:`activetrack.filters.jpda.jpda_probabilities` (the tracker's
``tracker.tracks.oversize_cluster``), never a silent one: every cluster pruned and pair dropped
is counted (:class:`Pruning`).

What is dropped: the gated pairs of smallest likelihood ratio ``l[t, j] = Pd N(nu; 0, S) /
lambda`` (below 1 the detection is more likely clutter than that track's), as if outside the
gate. The marginals are then the exact JPDA of the pruned gate (BDH 2009, eq. 40-41): the
joint events that give a dropped pair's detection to its track are left out of the sums,
so the probability mass lost is that of those events, and each is weighed by the product of
its pairs' ratios, a dropped ratio among them. It is a gating approximation, as the
chi-square gate itself is (Pg < 1 leaves the far tail out the same way).

How many: a geometric schedule on the count of the weakest pairs dropped (1, 2, 4, ...; ties
in the ratio go together) until every part the cluster splits into fits, then a bisection back
towards the first count that did not; a part fits when it has one track, when it would be
enumerated (at most ``enumeration_events`` joint events by the product bound), or when the
upper bound on its net's edges (:func:`~activetrack.filters.jpda_net.net_edges_upper`, never
under the edges built) is within ``max_edges``. Each test costs the parts' track orders and
bounds, never a net; the nets of the parts are then built once, each within ``max_edges``.
A track that cannot miss (``Pd Pg = 1``) keeps its strongest pair.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from activetrack.arraytypes import BoolArray, FloatArray
from activetrack.filters.jpda_net import (
    NetOversize,
    events_bound,
    gate_clusters,
    net_edges_upper,
    track_order,
)

__all__ = ["Pruning", "prune_gate"]


@dataclass
class Pruning:
    """What pruning did, summed over the calls it was given to: oversize ``clusters`` pruned
    and gated ``pairs`` dropped from them."""

    clusters: int = 0
    pairs: int = 0


def prune_gate(log_w: FloatArray, *, max_edges: int, enumeration_events: int) -> BoolArray:
    """The pruned gate ``(T, m)`` of one oversize cluster from its log weights ``log_w``
    ``(T, m + 1)`` (column 0 no measurement, ``-inf`` an ungated pair or an impossible miss):
    the gated pairs kept (module docstring). :class:`NetOversize` if even dropping every pair
    it may leaves a part that does not fit."""
    ratios = log_w[:, 1:]
    gated = np.isfinite(ratios)
    droppable = gated.copy()
    no_miss = np.flatnonzero(~np.isfinite(log_w[:, 0]) & gated.any(axis=1))
    droppable[no_miss, np.argmax(ratios[no_miss], axis=1)] = False  # its strongest pair stays
    levels = np.sort(ratios[droppable])  # the candidates' log ratios, weakest first

    def kept(count: int) -> BoolArray:
        return gated & ~(droppable & (ratios <= levels[count - 1])) if count else gated

    def fits(count: int) -> bool:
        return _fits(kept(count), max_edges, enumeration_events)

    bad, good = 0, 1
    while not fits(min(good, levels.size)):
        if good >= levels.size:
            T, m = gated.shape
            raise NetOversize(
                f"JPDA hypothesis net of a cluster of {T} tracks and {m} measurements does not "
                f"fit max_edges={max_edges} edges even with every droppable pair of its "
                f"{int(gated.sum())} dropped: raise max_edges",
                tracks=T,
                measurements=m,
                pairs=int(gated.sum()),
                max_edges=max_edges,
            )
        bad, good = good, 2 * good
    good = min(good, levels.size)
    while good - bad > 1:  # a fitting count between the last failing one and the first fitting
        mid = (bad + good) // 2
        bad, good = (bad, mid) if fits(mid) else (mid, good)
    return kept(good)


def _fits(gated: BoolArray, max_edges: int, enumeration_events: int) -> bool:
    """Every part of the gate ``gated`` is one track, enumerated, or has a net within
    ``max_edges`` by the upper bound."""
    for tracks, measurements in gate_clusters(gated):
        if tracks.size == 1:
            continue
        part = gated[np.ix_(tracks, measurements)]
        if events_bound(part) <= enumeration_events:
            continue
        if net_edges_upper(part, track_order(part)) > max_edges:
            return False
    return True
