"""Gating, JPDA association probabilities and the PDA / JPDA update of Gaussian tracks.

Model (parametric JPDA with Poisson clutter; Bar-Shalom, Daum & Huang, "The probabilistic data
association filter", IEEE Control Systems Magazine 29(6), 2009, sec. "JPDAF"; Bar-Shalom & Li,
*Multitarget-Multisensor Tracking*, 1995, ch. 6).  One scan of ``m`` unlabelled measurements
``z_1..z_m`` from one sensor; ``T`` Gaussian tracks ``N(x_t, P_t)``; track ``t`` is detected with
probability ``Pd_t`` and its measurement falls in its gate with probability ``Pg_t``; false alarms
are Poisson with density ``lambda`` per unit of ``z``.

Per track, from the sensor's own maths::

    zhat_t = h(x_t),  H_t = dh/dx (x_t),  S_t = H_t P_t H_t^T + R,  nu_tj = z_j - zhat_t (wrapped)

Gate (chi-square): ``nu_tj^T S_t^-1 nu_tj <= gamma``, ``Pg = F_{chi2, dim_z}(gamma)``.
Likelihood ratio of "z_j is track t's" against clutter, zero outside the gate::

    l[t, j] = Pd_t N(nu_tj; 0, S_t) / lambda

A feasible joint event ``theta`` gives each track at most one measurement and each measurement
at most one track; with Poisson clutter its posterior probability is (BDH 2009, eq. 40-41)

    P(theta | Z) = (1/c) prod_{t assigned j} l[t, j] prod_{t unassigned} (1 - Pd_t Pg_t)

and the marginals ``beta[t, j] = sum_{theta: t -> j} P(theta | Z)`` (``j = 0``: no measurement)
are found here exactly, per cluster of the gate, on a hypothesis net whose size follows the
measurements shared between tracks rather than the number of events (efficient hypothesis
management, :mod:`activetrack.filters.jpda_net`; memory bound ``max_edges``, beyond which a
cluster raises or, as the named option ``oversize="prune"``, loses its weakest gated pairs,
counted: :mod:`activetrack.filters.jpda_prune`); enumeration of the events is kept as the
reference.  With one track this is the PDAF:
``beta_j = l_j / (1 - Pd Pg + sum_i l_i)``, ``beta_0 = (1 - Pd Pg) / (1 - Pd Pg + sum_i l_i)``.

Update of each track with its betas (the PDAF update, BDH 2009 eq. 23-27)::

    K = P H^T S^-1,   nu = sum_j beta_j nu_j,   x+ = x + K nu
    P_c = (I - K H) P (I - K H)^T + K R K^T                 (Joseph form)
    P~  = K (sum_j beta_j nu_j nu_j^T - nu nu^T) K^T        (spread of the innovations)
    P+  = beta_0 P + (1 - beta_0) P_c + P~

linearised once at the predicted mean (exact for a linear sensor).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal, get_args

import numpy as np
import numpy.typing as npt

from activetrack.arraytypes import ArrayLike, BoolArray, FloatArray
from activetrack.checks import require_int, require_positive
from activetrack.filters.jpda_net import (
    DEFAULT_MAX_EDGES,
    GateClusters,
    NetOversize,
    events_bound,
    gate_clusters,
    net_edges_lower,
    net_marginals,
    track_order,
)
from activetrack.filters.jpda_prune import Pruning, prune_gate
from activetrack.models.base import MotionModel, SensorModel
from activetrack.models.sensors import state_jacobian
from activetrack.stats import chi2_cdf

__all__ = [
    "DEFAULT_MAX_EDGES",
    "DEFAULT_MAX_EVENTS",
    "ENUMERATION_EVENTS",
    "OVERSIZE",
    "JPDAResult",
    "NetOversize",
    "Pruning",
    "gate",
    "gate_probability",
    "jpda_association",
    "jpda_probabilities",
    "jpda_probabilities_enumerated",
    "jpda_update",
    "likelihood_ratios",
    "mahalanobis2",
    "pda_nis",
    "pda_residuals",
    "pda_update",
    "pda_update_many",
    "predict_measurements",
]

DEFAULT_MAX_EVENTS = 200_000
# jpda_probabilities enumerates a cluster of at most this many events (product bound) rather
# than build its net: the same exact sums, with less overhead on the many small clusters.
ENUMERATION_EVENTS = 4096
# What jpda_probabilities does with a cluster whose net exceeds max_edges: raise NetOversize
# (exact everywhere), or prune its weakest pairs (activetrack.filters.jpda_prune, counted).
Oversize = Literal["error", "prune"]
OVERSIZE = get_args(Oversize)
_NO_EVENT = (
    "jpda_probabilities: no feasible joint event has positive probability "
    "(a track with Pd * Pg = 1 has no measurement in its gate)"
)

IntArray = npt.NDArray[np.intp]
Residual = Callable[[ArrayLike, ArrayLike], FloatArray]


def gate_probability(gamma: float, dim_z: int) -> float:
    """``Pg = F_{chi2, dim_z}(gamma)``: the probability that the target's own measurement is in
    the gate ``nu^T S^-1 nu <= gamma``."""
    gamma = require_positive("gamma", gamma)
    return chi2_cdf(gamma, dim_z)


def _as_measurements(z: ArrayLike, dim_z: int) -> FloatArray:
    Z = np.asarray(z, dtype=float)
    if Z.size == 0:
        return np.zeros((0, dim_z))
    Z = Z.reshape(-1, dim_z) if Z.ndim == 1 and dim_z == 1 else Z
    if Z.ndim != 2 or Z.shape[1] != dim_z or not np.isfinite(Z).all():
        raise ValueError(f"z must be a finite array of shape (m, {dim_z}), got {np.shape(z)}")
    return Z


def _residuals(Z: FloatArray, z_pred: FloatArray, residual: Residual) -> FloatArray:
    """``nu[t, j] = residual(z_j, zhat_t)``, shape ``(T, m, dim_z)``."""
    return np.asarray(residual(Z[None, :, :], z_pred[:, None, :]), dtype=float)


def mahalanobis2(nu: FloatArray, S: FloatArray) -> FloatArray:
    """``nu[t, j]^T S_t^-1 nu[t, j]`` for residuals ``(T, m, d)`` and ``S`` ``(T, d, d)``:
    ``(T, m)``, through the Cholesky factor of each ``S_t`` (raises ValueError if not SPD)."""
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        raise ValueError("S: innovation covariance is not positive definite") from None
    if nu.shape[1] == 0:
        return np.zeros(nu.shape[:2])
    w = np.linalg.solve(L, np.swapaxes(nu, -1, -2))  # (T, d, m) = L^-1 nu^T
    return np.asarray(np.einsum("tdm,tdm->tm", w, w), dtype=float)


def pda_nis(nu: FloatArray, S: FloatArray, beta: FloatArray) -> FloatArray:
    """The NIS of ``T`` tracks' PDA updates ``(T,)``: the expected ``nu_j^T S^-1 nu_j`` of the
    target's detection given that one of the scan's detections is the target's, ``sum_j
    beta_j nu_j^T S^-1 nu_j / (1 - beta_0)``, from residuals ``nu`` ``(T, m, d)``, innovation
    covariances ``S`` ``(T, d, d)`` and association probabilities ``beta`` ``(T, m + 1)``
    (column 0: no detection). A detection certainly the target's gives the EKF's NIS; NaN
    where ``beta_0`` = 1 (no update)."""
    B = np.asarray(beta, dtype=float)
    out = np.full(B.shape[0], math.nan)
    # Only the pairs with beta_j > 0 (inside the gate), not all T x m pairs a second time
    rows, cols = np.nonzero(B[:, 1:] > 0.0)
    if rows.size == 0:
        return out
    v = nu[rows, cols]  # (K, d)
    d2 = np.einsum("kd,kd->k", v, np.linalg.solve(S[rows], v[..., None])[..., 0])
    weighted = np.bincount(rows, weights=B[rows, cols + 1] * d2, minlength=B.shape[0])
    detected = 1.0 - B[:, 0]
    np.divide(weighted, detected, out=out, where=detected > 0.0)
    return out


def gate(
    z: ArrayLike, z_pred: ArrayLike, S: ArrayLike, gamma: float, *, residual: Residual
) -> BoolArray:
    """Chi-square gate: ``mask[t, j] = nu_tj^T S_t^-1 nu_tj <= gamma``, shape ``(T, m)``.

    z ``(m, d)``, z_pred ``(T, d)``, S ``(T, d, d)``; gamma e.g. 9 for 3 sigmas; ``residual``
    the sensor's (required: a plain difference is wrong for angles near +-pi).
    """
    gamma = require_positive("gamma", gamma)
    zp = np.asarray(z_pred, dtype=float)
    if zp.ndim != 2:
        raise ValueError(f"z_pred must have shape (T, d), got {zp.shape}")
    d = zp.shape[1]
    Sa = np.asarray(S, dtype=float)
    if Sa.shape != (zp.shape[0], d, d):
        raise ValueError(f"S must have shape ({zp.shape[0]}, {d}, {d}), got {Sa.shape}")
    Z = _as_measurements(z, d)
    d2 = mahalanobis2(_residuals(Z, zp, residual), Sa)
    return np.asarray(d2 <= gamma, dtype=bool)


def predict_measurements(
    means: ArrayLike,
    covs: ArrayLike,
    sensor: SensorModel,
    sensor_state: ArrayLike,
    model: MotionModel,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(zhat, H, S)`` of every track: ``(T, d)``, ``(T, d, n)``, ``(T, d, d)``, from the
    sensor's ``measure`` and Jacobian (chained with the model's ``kinematics_jacobian``)."""
    X = np.asarray(means, dtype=float)
    P = np.asarray(covs, dtype=float)
    if X.ndim != 2 or P.shape != (X.shape[0], X.shape[1], X.shape[1]):
        raise ValueError(f"means (T, n) and covs (T, n, n) expected, got {X.shape}, {P.shape}")
    s = np.asarray(sensor_state, dtype=float)
    zhat = np.asarray(sensor.measure(model.kinematics(X), s), dtype=float).reshape(X.shape[0], -1)
    H = np.asarray(state_jacobian(sensor, model, X, s), dtype=float)
    S = H @ P @ np.swapaxes(H, -1, -2) + np.asarray(sensor.R, dtype=float)
    return zhat, H, 0.5 * (S + np.swapaxes(S, -1, -2))


def likelihood_ratios(
    nu: FloatArray, S: FloatArray, pd: ArrayLike, clutter_density: float, gamma: float
) -> tuple[FloatArray, BoolArray]:
    """``(l, mask)``: ``l[t, j] = Pd_t N(nu_tj; 0, S_t) / lambda`` inside the gate, 0 outside;
    ``mask`` the gate.  ``nu`` ``(T, m, d)`` wrapped residuals, ``S`` ``(T, d, d)``,
    ``clutter_density`` lambda > 0 per unit of z."""
    lam = require_positive("clutter_density", clutter_density)
    T, _, d = nu.shape
    pd_t = _per_track("pd", pd, T)
    d2 = mahalanobis2(nu, S)
    mask = np.asarray(d2 <= gamma, dtype=bool)
    log_det = np.linalg.slogdet(S)[1]  # (T,)
    log_n = -0.5 * (d2 + log_det[:, None] + d * math.log(2.0 * math.pi))
    l = np.where(mask, pd_t[:, None] * np.exp(log_n) / lam, 0.0)
    return np.asarray(l, dtype=float), mask


def _per_track(name: str, value: ArrayLike, T: int) -> FloatArray:
    v = np.broadcast_to(np.asarray(value, dtype=float), (T,))
    if not (np.isfinite(v).all() and (v >= 0.0).all() and (v <= 1.0).all()):
        raise ValueError(f"{name} must be in [0, 1], got {value!r}")
    return np.asarray(v, dtype=float)


def _feasible_events(gated: BoolArray, max_events: int) -> IntArray:
    """All feasible joint events as an int array ``(E, T)``: entry ``j`` in 0..m (0 = none),
    each measurement used at most once, only gated pairs.  Built track by track, vectorised
    over the partial events; raises ValueError past ``max_events``."""
    T, m = gated.shape
    events = np.zeros((1, 0), dtype=np.intp)
    used = np.zeros((1, m + 1), dtype=bool)  # column 0 ("none") is never marked
    for t in range(T):
        options = np.concatenate(([0], np.flatnonzero(gated[t]) + 1))
        ok = ~used[:, options]  # (E, k): option free in this partial event
        ok[:, 0] = True
        n_new = int(ok.sum())
        if n_new > max_events:
            raise ValueError(
                f"JPDA enumeration needs more than max_events={max_events} joint events "
                f"({T} tracks, {m} measurements, {int(gated.sum())} gated pairs): split the "
                "tracks into independent clusters, tighten the gate or raise max_events"
            )
        rows, cols = np.nonzero(ok)
        choice = options[cols]
        events = np.column_stack((events[rows], choice))
        used = used[rows]
        used[np.arange(rows.size), choice] = True
        used[:, 0] = False
    return events


def _ratios(likelihood_ratios: ArrayLike) -> FloatArray:
    L = np.asarray(likelihood_ratios, dtype=float)
    if L.ndim != 2 or not (np.isfinite(L).all() and (L >= 0.0).all()):
        raise ValueError(f"likelihood_ratios must be finite, >= 0, of shape (T, m); got {L.shape}")
    return L


def _log_weights(likelihood_ratios: ArrayLike, pd: ArrayLike, pg: ArrayLike) -> FloatArray:
    """``log w`` ``(T, m + 1)``: ``log(1 - Pd_t Pg_t)`` then ``log l[t, j]``, -inf for zero."""
    L = _ratios(likelihood_ratios)
    T = L.shape[0]
    miss = 1.0 - _per_track("pd", pd, T) * _per_track("pg", pg, T)
    with np.errstate(divide="ignore"):
        return np.asarray(np.log(np.column_stack((miss, L))), dtype=float)


def jpda_probabilities(
    likelihood_ratios: ArrayLike,
    pd: ArrayLike,
    pg: ArrayLike,
    *,
    max_edges: int = DEFAULT_MAX_EDGES,
    clusters: GateClusters | None = None,
    oversize: Oversize = "error",
    pruning: Pruning | None = None,
) -> FloatArray:
    """JPDA marginal association probabilities ``beta`` ``(T, m + 1)``; column 0 is "no
    measurement", column ``j`` measurement ``j - 1``.

    ``l`` ``(T, m)`` zero outside the gate; pd, pg scalars or ``(T,)``.  Exact: the tracks are
    split into clusters (connected components of the gate, independent of each other) and each
    cluster's marginals are summed over all its feasible events, on a hypothesis net
    (:mod:`activetrack.filters.jpda_net`) or, for a cluster of at most
    :data:`ENUMERATION_EVENTS` events by the product bound, by enumerating them (the same sums,
    cheaper there); in log space (no overflow).  ValueError when no event is possible
    (``Pd Pg = 1`` and no gated measurement).  :func:`jpda_probabilities_enumerated`
    enumerates every cluster.

    ``oversize``: a cluster whose net would exceed ``max_edges`` edges (memory) raises
    :class:`~.jpda_net.NetOversize` (a ValueError; ``"error"``, the default), or
    (``"prune"``) loses its weakest gated pairs until its parts fit and takes the exact JPDA
    of the pruned gate (:mod:`activetrack.filters.jpda_prune`: a gating approximation),
    counted in ``pruning`` if given. A cluster whose net fits is the same, to the bit, either
    way.

    ``clusters``: the caller's gate and its clusters (:class:`~.jpda_net.GateClusters`), the
    gate holding every pair of ``l > 0``, so that a scan is clustered once: each cluster is
    split where its ``l`` is 0 (a gated pair's ratio can underflow), which gives the clusters
    of ``l > 0`` and so the same marginals, to the bit (ValueError naming ``clusters`` for a
    pair of ``l > 0`` outside its gate).
    """
    L = _ratios(likelihood_ratios)  # only the gated pairs are read after the checks
    T, _ = L.shape
    miss = 1.0 - _per_track("pd", pd, T) * _per_track("pg", pg, T)
    max_edges = require_int("max_edges", max_edges, 1, 2**62)
    if oversize not in OVERSIZE:
        raise ValueError(f"oversize: must be one of {OVERSIZE}, got {oversize!r}")
    positive = L > 0.0
    if clusters is None:
        found = gate_clusters(positive)
    elif isinstance(clusters, GateClusters):
        found = clusters.split(positive)
    else:
        raise ValueError(f"clusters: a GateClusters or None, got {type(clusters).__name__}")
    return _marginals(L, miss, found, max_edges, oversize == "prune", pruning)


def _marginals(
    L: FloatArray,
    miss: FloatArray,
    found: list[tuple[IntArray, IntArray]],
    max_edges: int,
    prune: bool,
    pruning: Pruning | None,
) -> FloatArray:
    """:func:`jpda_probabilities` of the ratios ``L`` ``(T, m)`` and miss weights ``miss``
    ``(T,)`` on the clusters ``found`` of ``L > 0``: an oversize cluster raises, or with
    ``prune`` is pruned, counted in ``pruning`` (if given)."""
    T, m = L.shape
    beta = np.zeros((T, m + 1))
    alone = [(tracks[0], measurements) for tracks, measurements in found if tracks.size == 1]
    _pdaf_marginals(beta, alone, L, miss)
    for tracks, measurements in found:
        if tracks.size == 1:
            continue
        columns = np.concatenate(([0], measurements + 1))
        ratios = L[np.ix_(tracks, measurements)]
        with np.errstate(divide="ignore"):
            cluster = np.log(np.column_stack((miss[tracks], ratios)))
        if events_bound(ratios > 0.0) <= ENUMERATION_EVENTS:
            beta[np.ix_(tracks, columns)] = _enumerated_marginals(cluster, ENUMERATION_EVENTS)
        elif not prune:
            beta[np.ix_(tracks, columns)] = net_marginals(cluster, max_edges=max_edges)
        else:
            beta[np.ix_(tracks, columns)] = _net_or_pruned(
                cluster, ratios, miss[tracks], max_edges, pruning
            )
    # A sum of normalised weights can round one ulp above 1 (seen: 1 + 2e-16 next to 1e-25),
    # which a PDA update rightly refuses as a probability.
    return np.minimum(beta, 1.0)


def _net_or_pruned(
    cluster: FloatArray,
    ratios: FloatArray,
    miss: FloatArray,
    max_edges: int,
    pruning: Pruning | None,
) -> FloatArray:
    """One cluster's marginals on its net if it fits (tried unless the lower bound on its
    edges already exceeds ``max_edges``), else those of its pruned gate, counted."""
    gated = ratios > 0.0
    order = track_order(gated)
    if not (miss > 0.0).all() or net_edges_lower(gated, order) <= max_edges:
        try:
            return net_marginals(cluster, max_edges=max_edges, order=order)
        except NetOversize:
            pass
    kept = prune_gate(cluster, max_edges=max_edges, enumeration_events=ENUMERATION_EVENTS)
    if pruning is not None:
        pruning.clusters += 1
        pruning.pairs += int(gated.sum() - kept.sum())
    pruned = np.where(kept, ratios, 0.0)
    # Every part fits (prune_gate): their exact marginals, as for the pruned gate whole.
    return _marginals(pruned, miss, gate_clusters(kept), max_edges, False, None)


def jpda_probabilities_enumerated(
    likelihood_ratios: ArrayLike,
    pd: ArrayLike,
    pg: ArrayLike,
    *,
    max_events: int = DEFAULT_MAX_EVENTS,
) -> FloatArray:
    """:func:`jpda_probabilities` by exact enumeration of all feasible joint events at once (no
    clustering), in log space: the reference the hypothesis net is tested against.  Its cost
    is the number of events; ValueError beyond ``max_events``."""
    log_w = _log_weights(likelihood_ratios, pd, pg)
    if log_w.shape[0] == 0:
        return np.zeros(log_w.shape)
    return np.minimum(_enumerated_marginals(log_w, max_events), 1.0)


def _pdaf_marginals(
    beta: FloatArray, alone: list[tuple[Any, IntArray]], L: FloatArray, miss: FloatArray
) -> None:
    """Into ``beta``, the marginals of the tracks that share no measurement, ``alone`` (each
    track with its gated measurements): each row's weights ``1 - Pd Pg`` and ``l[t, j]``
    normalised (the PDAF), over its possible options only, all rows in one pass (each row's
    sum as its enumeration sums it)."""
    if not alone:
        return
    tracks = np.array([t for t, _ in alone], dtype=np.intp)
    gated = [measurements for _, measurements in alone]
    rows = np.repeat(tracks, [g.size for g in gated])
    cols = np.concatenate(gated).astype(np.intp)
    can_miss = tracks[miss[tracks] > 0.0]
    with np.errstate(divide="ignore"):
        log_miss = np.log(miss[can_miss])
    # Entries (track, column, log weight), sorted by track then column: "none" first.
    r = np.concatenate((can_miss, rows))
    c = np.concatenate((np.zeros(can_miss.size, dtype=np.intp), cols + 1))
    v = np.concatenate((log_miss, np.log(L[rows, cols])))
    order = np.lexsort((c, r))
    r, c, v = r[order], c[order], v[order]
    first = np.concatenate(([True], r[1:] != r[:-1]))  # each row's first entry
    starts = np.flatnonzero(first) if r.size else r
    if starts.size != tracks.size:
        raise ValueError(_NO_EVENT)
    which = np.cumsum(first) - 1  # each entry's row among the tracks
    w = np.exp(v - np.maximum.reduceat(v, starts)[which])
    counts = np.diff(np.append(starts, r.size))
    total = np.empty(starts.size)
    for k in np.unique(counts):  # rows of k options as a (rows, k) block: sums as ndarray.sum
        same = np.flatnonzero(counts == k)
        total[same] = w[starts[same][:, None] + np.arange(k)].sum(axis=1)
    beta[r, c] = w / total[which]


def _enumerated_marginals(log_l: FloatArray, max_events: int) -> FloatArray:
    """Marginals ``(T, m + 1)`` from log weights ``(T, m + 1)`` (-inf: impossible) by summing
    every feasible event's weight (BDH 2009 eq. 40-41)."""
    T, m1 = log_l.shape
    events = _feasible_events(np.isfinite(log_l[:, 1:]), max_events)
    log_w = log_l[np.arange(T)[None, :], events].sum(axis=1)  # (E,)
    top = float(np.max(log_w))
    if not math.isfinite(top):
        raise ValueError(_NO_EVENT)
    w = np.exp(log_w - top)
    w /= w.sum()
    beta = np.zeros((T, m1))
    for t in range(T):
        beta[t] = np.bincount(events[:, t], weights=w, minlength=m1)
    return beta


def pda_update(
    x: ArrayLike, P: ArrayLike, H: ArrayLike, R: ArrayLike, nu: ArrayLike, beta: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """PDAF update of one Gaussian track (module docstring): ``x`` ``(n,)``, ``P`` ``(n, n)``,
    ``H`` ``(d, n)``, ``R`` ``(d, d)``, residuals ``nu`` ``(m, d)`` (wrapped), ``beta``
    ``(m + 1,)`` with ``beta[0]`` for "no measurement".  Returns ``(x+, P+)``:
    :func:`pda_update_many` of one track."""
    x = np.asarray(x, dtype=float)
    P = np.asarray(P, dtype=float)
    H = np.asarray(H, dtype=float)
    R = np.asarray(R, dtype=float)
    b = np.asarray(beta, dtype=float)
    d = H.shape[0]
    nu = np.asarray(nu, dtype=float).reshape(-1, d)
    if b.shape != (nu.shape[0] + 1,):
        raise ValueError(f"beta must have shape ({nu.shape[0] + 1},), got {b.shape}")
    X_new, P_new = pda_update_many(x[None], P[None], H[None], R, nu[None], b[None])
    return X_new[0], P_new[0]


def pda_update_many(
    X: FloatArray, P: FloatArray, H: FloatArray, R: FloatArray, nu: FloatArray, B: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The PDAF update of ``G`` tracks at once (module docstring; Bar-Shalom & Tse 1975):
    means ``(G, n)``, covariances ``(G, n, n)``, Jacobians ``(G, d, n)``, ``R`` ``(d, d)``,
    residuals ``(G, m, d)``, probabilities ``(G, m + 1)`` (column 0: no measurement). K = P H^T
    S^-1 by a solve; the combined innovation nu_c = sum_j beta_j nu_j; P+ = beta_0 P + (1 -
    beta_0) P_c + K (sum_j beta_j nu_j nu_j^T - nu_c nu_c^T) K^T with P_c the Joseph form.
    Each track's numbers are its own (numpy runs a stacked product track by track)."""
    HT = np.swapaxes(H, 1, 2)
    PHT = P @ HT
    S = H @ PHT + R
    K = np.swapaxes(np.linalg.solve(S, np.swapaxes(PHT, 1, 2)), 1, 2)  # P H^T S^-1
    b0, bj = B[:, 0], B[:, 1:]
    nu_c = (bj[:, None, :] @ nu)[:, 0, :]  # combined innovations (G, d)
    spread = (np.swapaxes(nu, 1, 2) * bj[:, None, :]) @ nu - nu_c[:, :, None] * nu_c[:, None, :]
    KT = np.swapaxes(K, 1, 2)
    I_KH = np.eye(X.shape[1]) - K @ H
    P_c = I_KH @ P @ np.swapaxes(I_KH, 1, 2) + K @ R @ KT
    P_new = b0[:, None, None] * P + (1.0 - b0)[:, None, None] * P_c + K @ spread @ KT
    X_new = X + (K @ nu_c[:, :, None])[:, :, 0]
    return X_new, 0.5 * (P_new + np.swapaxes(P_new, 1, 2))


@dataclass(frozen=True)
class JPDAResult:
    """One JPDA scan: updated ``means`` ``(T, n)`` and ``covs`` ``(T, n, n)``, the association
    probabilities ``beta`` ``(T, m + 1)`` (column 0: no measurement), the gate ``(T, m)`` and
    the likelihood ratios ``(T, m)``."""

    means: FloatArray
    covs: FloatArray
    beta: FloatArray
    gated: BoolArray
    likelihood_ratios: FloatArray


def jpda_association(
    means: ArrayLike,
    covs: ArrayLike,
    z: ArrayLike,
    sensor: SensorModel,
    sensor_state: ArrayLike,
    model: MotionModel,
    *,
    clutter_density: float,
    gamma: float,
    pd: ArrayLike | None = None,
    max_edges: int = DEFAULT_MAX_EDGES,
) -> JPDAResult:
    """Gate, likelihood ratios and marginals ``beta`` of ``T`` predicted tracks (``means``
    ``(T, n)``, ``covs`` ``(T, n, n)``) with one scan ``z`` ``(m, d)`` of ``sensor`` at pv
    ``sensor_state``, the tracks left as predicted (each filter's ``update_pda`` takes its
    row); ``clutter_density`` per unit of z, chi-square gate ``gamma``, ``pd`` per track
    (default ``sensor.pd``); exact marginals per cluster of the gate (:func:`jpda_probabilities`,
    ``max_edges`` its memory bound)."""
    return _associate(
        means, covs, z, sensor, sensor_state, model,
        clutter_density=clutter_density, gamma=gamma, pd=pd, max_edges=max_edges,
    )[0]  # fmt: skip


def _associate(
    means: ArrayLike,
    covs: ArrayLike,
    z: ArrayLike,
    sensor: SensorModel,
    sensor_state: ArrayLike,
    model: MotionModel,
    *,
    clutter_density: float,
    gamma: float,
    pd: ArrayLike | None = None,
    max_edges: int = DEFAULT_MAX_EDGES,
) -> tuple[JPDAResult, FloatArray, FloatArray]:
    """:func:`jpda_association` and the Jacobians ``H`` ``(T, d, n)`` and wrapped residuals
    ``nu`` ``(T, m, d)`` it computed, for the update."""
    X = np.asarray(means, dtype=float)
    P = np.asarray(covs, dtype=float)
    zhat, H, S = predict_measurements(X, P, sensor, sensor_state, model)
    T, d = zhat.shape
    Z = _as_measurements(z, d)
    nu = _residuals(Z, zhat, sensor.residual)
    pd_t = _per_track("pd", sensor.pd if pd is None else pd, T)
    l, mask = likelihood_ratios(nu, S, pd_t, clutter_density, gamma)
    beta = jpda_probabilities(l, pd_t, gate_probability(gamma, d), max_edges=max_edges)
    return JPDAResult(X, P, beta, mask, l), H, nu


def pda_residuals(
    x: ArrayLike,
    P: ArrayLike,
    z: ArrayLike,
    sensor: SensorModel,
    sensor_state: ArrayLike,
    model: MotionModel,
) -> tuple[FloatArray, FloatArray]:
    """``(H, nu)`` for :func:`pda_update`: the Jacobian ``(d, n)`` at ``x`` ``(n,)`` and the
    wrapped residuals ``(m, d)`` of ``z`` ``(m, d)``."""
    zhat, H, _ = predict_measurements(
        np.asarray(x, dtype=float)[None],
        np.asarray(P, dtype=float)[None],
        sensor,
        sensor_state,
        model,
    )
    Z = _as_measurements(z, zhat.shape[1])
    return H[0], _residuals(Z, zhat, sensor.residual)[0]


def jpda_update(
    means: ArrayLike,
    covs: ArrayLike,
    z: ArrayLike,
    sensor: SensorModel,
    sensor_state: ArrayLike,
    model: MotionModel,
    **association: Any,
) -> JPDAResult:
    """JPDA-EKF update of ``T`` predicted tracks: :func:`jpda_association` (its arguments),
    then the PDAF update of each track. One track is the PDAF; a track with no gated
    measurement keeps its prediction."""
    a, H, nu = _associate(means, covs, z, sensor, sensor_state, model, **association)
    R = np.asarray(sensor.R, dtype=float)
    new_X = a.means.copy()
    new_P = a.covs.copy()
    for t in range(a.means.shape[0]):
        if a.beta[t, 0] < 1.0:  # the association's own H and residuals, not recomputed
            new_X[t], new_P[t] = pda_update(a.means[t], a.covs[t], H[t], R, nu[t], a.beta[t])
    return JPDAResult(new_X, new_P, a.beta, a.gated, a.likelihood_ratios)
