"""Tracks and their management: M-of-N confirmation and deletion, probability of existence.

A :class:`Track` is one filter (any registered one) with its id, status and look history;
:class:`TrackManager` holds the live tracks and applies the rules of ``tracker.tracks`` once per
epoch (M-of-N: Blackman & Popoli, *Design and Analysis of Modern Tracking Systems*, 1999):

- a **look** is an epoch at which a scan's field of view held the track's predicted position, a
  **hit** a look with a detection in its gate (the detection that starts a track is its first);
- a tentative track is **confirmed** once it has ``confirm_m`` hits in its last ``confirm_n``
  looks and the existence below; it is **deleted** once ``hits + (confirm_n - looks) <
  confirm_m`` (it can no longer reach M; past ``confirm_n`` looks each look without a hit uses
  up one of its spare hits);
- a confirmed track is deleted after ``delete_misses`` consecutive looks without a hit, any track
  once its position standard deviation (sqrt of the largest eigenvalue of its xy covariance)
  exceeds ``max_position_std`` (lost: a planner cannot use it);
- **coalescence** (two JPDA tracks drawn onto one target, Fitzgerald 1985; Blom & Bloem 2000):
  of two confirmed tracks within Mahalanobis distance ``d^2 = dx^T (P_a + P_b)^-1 dx <=``
  :func:`coalesce_d2` at ``COALESCE_LOOKS`` consecutive joint looks the less supported is
  deleted (lower existence, then fewer hits per look, then the younger: the larger id). ``dx``
  is the whole state, as in the track-to-track association test (Bar-Shalom 1981): two tracks
  on one target agree in velocity too, while targets that cross, even crowded at one point,
  differ in it and are kept;
- **probability of existence** (IPDA: Musicki, Evans & Stankovic, IEEE TAC 39(6), 1994; among
  tracks that share detections LM-IPDA: Musicki & La Scala, IEEE TAES 44(3), 2008): predicted
  by ``existence_survival`` once per epoch at the track's first scan, updated by every scan that
  held it (:func:`existence_update`, with Pd times the chance that the target is in the field
  of view: a scan whose sector missed the track lowers nothing); 1 for a track from a prior,
  ``EXISTENCE_INIT`` from a detection. Confirmation also needs ``existence >=
  existence_confirm``; a tentative track past ``confirm_n`` looks is deleted ("existence")
  below ``existence_delete``; a confirmed track is terminated below ``existence_terminate``,
  a threshold of its own (Musicki's IPDA practice, confirm ~0.9-0.95 and terminate
  ~0.01-0.05: at Pd 0.9 a confirmed track goes at its 4th consecutive miss, 1.0 -> 0.83 ->
  0.31 -> 0.043 -> 0.0045, not at its 3rd), and one from a prior below
  ``existence_terminate_prior`` (lower, by default its 5th miss: its target may never be
  picked up again, as bearings start no track and beams look only where tracks are). A
  prior's track that drifted off its target is thus deleted rather than kept as a false
  track, and a radar's detections of the target can start a new one. A detection that a sharper
  track explains counts as a hit for M-of-N but barely raises a wide track's existence (LM-IPDA
  adds the other track's detection density to its clutter density), so wide duplicates and
  clutter tracks fed by stray detections die out.
"""

from __future__ import annotations

import functools
import math
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from activetrack.arraytypes import FloatArray
from activetrack.checks import symmetrize
from activetrack.data import CONFIRMED, TENTATIVE, TrackEstimate
from activetrack.filters.jpda import Oversize
from activetrack.filters.measurement import TrackingFilter
from activetrack.models.base import MotionModel
from activetrack.stats import chi2_quantile
from activetrack.tracking.spatial import close_pairs, largest_xy_eigenvalue


class TrackManagementConfig(Protocol):
    """The M-of-N and deletion settings (a scenario's ``tracker.tracks``,
    :class:`activetrack.scenarios.schema.TrackManagementConfig`, or any object with them)."""

    gate_sigmas: float
    confirm_m: int
    confirm_n: int
    delete_misses: int
    init_speed_std: float
    max_position_std: float
    max_tracks: int
    initiate: bool
    existence_confirm: float
    existence_delete: float
    existence_terminate: float
    existence_terminate_prior: float
    existence_survival: float  # per epoch (IPDA's Markov chain: p11)
    oversize_cluster: Oversize  # "error" | "prune" (activetrack.filters.jpda.OVERSIZE)


__all__ = [
    "COALESCE_LOOKS",
    "COALESCE_QUANTILE",
    "EXISTENCE_INIT",
    "Track",
    "TrackManager",
    "coalesce_d2",
    "existence_update",
    "position_std",
    "weaker",
]

# The chi^2 quantile of the coalescence test: 1 - exp(-1/4), ~22 %, the quantile of a squared
# distance of 0.5 between two positions (2 dof), applied to the whole state.
COALESCE_QUANTILE = 1.0 - math.exp(-0.25)
COALESCE_LOOKS = 5  # consecutive joint looks


@functools.cache
def coalesce_d2(dim: int) -> float:
    """The squared Mahalanobis distance below which two ``dim``-state tracks are close: the
    chi^2 quantile :data:`COALESCE_QUANTILE` with ``dim`` degrees of freedom."""
    return chi2_quantile(COALESCE_QUANTILE, dim)  # 1.77 for pv states


EXISTENCE_INIT = 0.2  # a track started from one detection
_P_MAX = 1.0 - 1e-9  # cap of LM-IPDA's a priori probability that a detection is a track's


def position_std(cov: FloatArray) -> FloatArray:
    """sqrt of the largest eigenvalue of the xy block of pv covariances ``(..., 4, 4)`` [m],
    ``(...)`` (one LAPACK call per matrix, stacked or not)."""
    C = np.asarray(cov, dtype=float)
    return np.sqrt(np.maximum(np.linalg.eigvalsh(C[..., [0, 2], :][..., [0, 2]])[..., -1], 0.0))


def existence_update(
    existence: FloatArray, ratios: FloatArray, pd: float | FloatArray, pg: float
) -> FloatArray:
    """One scan's LM-IPDA update of the probabilities of existence ``(T,)`` of the tracks the
    scan looked at (Musicki & La Scala 2008; with one track it is IPDA, Musicki, Evans &
    Stankovic 1994).

    ratios ``(T, m)``: ``N(z_j; zhat_t, S_t) / rho`` for the detections in track t's gate, 0
    outside it (rho: the clutter density per unit of z); pd: detection probability, one or
    ``(T,)`` (per track: Pd times the probability that the target is in the field of view);
    pg: gate probability. With ``p_tj = N_tj / Pg`` (the detection's density, gated):

    - ``P_tj = psi_t Pd Pg p_tj / sum_i p_ti``: a priori, z_j is track t's detection;
    - ``Omega_tj = rho + sum_{s != t} P_sj p_sj / (1 - P_sj)``: z_j's clutter density seen
      from track t, the other tracks' detections added to the clutter;
    - ``delta_t = Pd Pg - Pd sum_j N_tj / Omega_tj`` and ``psi_t <- (1 - delta_t) psi_t /
      (1 - delta_t psi_t)``. No gated detection: ``delta = Pd Pg``, psi falls.
    """
    psi = np.asarray(existence, dtype=float)
    A = np.asarray(ratios, dtype=float).reshape(psi.shape[0], -1)  # N / rho
    pd = np.broadcast_to(np.asarray(pd, dtype=float), psi.shape)
    total = A.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        P = np.where(total > 0.0, (psi * pd * pg)[:, None] * A / total, 0.0)
    P = np.minimum(P, _P_MAX)
    # P p / (1 - P) in units of rho: p = N / Pg = A rho / Pg
    other = P * (A / pg) / (1.0 - P)
    omega = 1.0 + other.sum(axis=0, keepdims=True) - other  # Omega / rho
    delta = pd * pg - pd * (A / omega).sum(axis=1)
    return (1.0 - delta) * psi / (1.0 - delta * psi)


@dataclass
class Track:
    """One track: its filter (the tracker's registered filter, any state), status and M-of-N
    history. ``mean`` / ``cov`` are the filter's pv kinematics ``(4,)`` / ``(4, 4)`` (the
    filter's own moments for a pv model), ``state`` / ``state_cov`` its moments in the model's
    state."""

    track_id: int
    status: str
    filter: TrackingFilter
    model: MotionModel
    born: int  # epoch it was started
    origin: str = ""
    priority: float = 1.0
    particle_based: bool = False
    looks: int = 0
    hits: int = 0
    run_of_misses: int = 0
    missed_detections: int = 0  # scans that covered it without a detection of it
    window: deque[bool] = field(default_factory=deque)  # hit per look, the last confirm_n
    samples: FloatArray | None = None
    existence: float = 1.0  # IPDA probability of existence (module docstring)
    nis: float = math.nan
    ess: float = math.nan

    @property
    def confirmed(self) -> bool:
        return self.status == CONFIRMED

    @property
    def state(self) -> FloatArray:
        return np.asarray(self.filter.mean, dtype=float)

    @property
    def state_cov(self) -> FloatArray:
        return np.asarray(self.filter.cov, dtype=float)

    @property
    def mean(self) -> FloatArray:
        """pv mean ``(4,)``."""
        x = self.state
        return x if self.model.state_is_pv else np.asarray(self.model.kinematics(x), dtype=float)

    @property
    def cov(self) -> FloatArray:
        """pv covariance ``(4, 4)``."""
        P = self.state_cov
        if self.model.state_is_pv:
            return P
        K = np.asarray(self.model.kinematics_jacobian(self.state), dtype=float)
        return symmetrize(K @ P @ K.T)

    def record_look(self, hit: bool, cfg: TrackManagementConfig) -> None:
        """Count one look (hit or not) and confirm a tentative track that reached M of N."""
        self.looks += 1
        self.hits += hit
        self.run_of_misses = 0 if hit else self.run_of_misses + 1
        self.window.append(hit)
        while len(self.window) > cfg.confirm_n:
            self.window.popleft()
        if (
            self.status == TENTATIVE
            and sum(self.window) >= cfg.confirm_m
            and self.existence >= cfg.existence_confirm
        ):
            self.status = CONFIRMED

    def deletion_reason(self, cfg: TrackManagementConfig, std: float) -> str | None:
        """Why the track must go ("unconfirmed", "misses", "position_std", "existence"), or
        None; ``std`` its :func:`position_std`."""
        if self.status == TENTATIVE and self.hits + cfg.confirm_n - self.looks < cfg.confirm_m:
            return "unconfirmed"
        if self.status == CONFIRMED and self.run_of_misses >= cfg.delete_misses:
            return "misses"
        if std > cfg.max_position_std:
            return "position_std"
        terminate = cfg.existence_terminate_prior if self.origin else cfg.existence_terminate
        if self.status == CONFIRMED and self.existence < terminate:
            return "existence"
        if (
            self.status == TENTATIVE
            and self.looks > cfg.confirm_n
            and self.existence < cfg.existence_delete
        ):
            return "existence"
        return None

    def estimate(
        self,
        epoch: int,
        moments: tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None = None,
    ) -> TrackEstimate:
        """The track as the tracker reports it; ``moments``: its ``(mean, cov, state,
        state_cov)`` where the caller read them (each its own array), else read here."""
        particles = getattr(self.filter, "weights", None) if self.particle_based else None
        mean, cov, state, state_cov = moments or (self.mean, self.cov, self.state, self.state_cov)
        return TrackEstimate(
            track_id=self.track_id,
            status=self.status,
            mean=mean,
            cov=cov,
            state=state,
            state_cov=state_cov,
            origin=self.origin,
            priority=self.priority,
            age=epoch - self.born,
            hits=self.hits,
            misses=self.looks - self.hits,
            missed_detections=self.missed_detections,
            existence=self.existence,
            nis=self.nis,
            ess=self.ess,
            particle_count=0 if particles is None else len(particles),
            samples=None if self.samples is None else self.samples.copy(),
        )


class TrackManager:
    """The live tracks by id, the id counter, and the per-epoch M-of-N rules (module
    docstring). ``deleted`` counts deletions by reason, ``not_started`` the detections that
    would have started a track beyond ``max_tracks``."""

    def __init__(self, cfg: TrackManagementConfig):
        self.cfg = cfg
        self.tracks: dict[int, Track] = {}
        self.next_id = 1
        self.deleted: Counter[str] = Counter()
        self.not_started = 0
        # confirmed pair (lower id first) -> joint close looks, only the pairs counting (> 0)
        self._close: dict[tuple[int, int], int] = {}
        self._partners: dict[int, set[int]] = {}  # track id -> the ids it shares a pair with

    def live(self) -> list[Track]:
        """Every live track, by id."""
        return [self.tracks[i] for i in sorted(self.tracks)]

    def new_id(self) -> int:
        """The next track id (1, 2, 3, ...; never reused)."""
        self.next_id += 1
        return self.next_id - 1

    def add(self, track: Track) -> None:
        self.tracks[track.track_id] = track

    @property
    def full(self) -> bool:
        return len(self.tracks) >= self.cfg.max_tracks

    def end_epoch(
        self,
        looked: dict[int, bool],
        pv_covs: Callable[[list[Track]], FloatArray] | None = None,
    ) -> None:
        """Apply one epoch's looks (track id -> hit) and every deletion rule; ``pv_covs``
        gives tracks' pv covariances ``(T, 4, 4)`` at once where the caller can (else each
        track's ``cov``)."""
        for track_id, hit in looked.items():
            if track_id in self.tracks:
                self.tracks[track_id].record_look(hit, self.cfg)
        live = self.live()
        covs = pv_covs(live) if pv_covs else np.array([track.cov for track in live])
        stds = position_std(np.asarray(covs, dtype=float).reshape(-1, 4, 4))
        for track, std in zip(live, stds, strict=True):
            reason = track.deletion_reason(self.cfg, float(std))
            if reason is not None:
                self._delete(track.track_id, reason)
        for track_id in self._coalesced(looked):
            self._delete(track_id, "coalesced")

    def _delete(self, track_id: int, reason: str) -> None:
        if self.tracks.pop(track_id, None) is not None:
            self.deleted[reason] += 1
        for other in self._partners.pop(track_id, ()):
            self._close.pop((min(track_id, other), max(track_id, other)), None)
            self._partners[other].discard(track_id)

    def _count(self, pair: tuple[int, int], count: int) -> None:
        if count:
            self._close[pair] = count
            self._partners.setdefault(pair[0], set()).add(pair[1])
            self._partners.setdefault(pair[1], set()).add(pair[0])
        elif self._close.pop(pair, None) is not None:
            self._partners[pair[0]].discard(pair[1])
            self._partners[pair[1]].discard(pair[0])

    def _coalesced(self, looked: dict[int, bool]) -> list[int]:
        """Update the closeness count of every pair of confirmed tracks both looked at this
        epoch; the less supported track of each pair that reached ``COALESCE_LOOKS``
        (:func:`weaker`). Only the pairs a k-d tree finds within reach are tested
        (:func:`~activetrack.tracking.spatial.close_pairs`, a superset of the close ones); every
        other pair is not close, and its count goes to 0."""
        seen = [t for t in self.live() if t.confirmed and t.track_id in looked]
        if len(seen) < 2:  # no pair both seen: every count stays
            return []
        means = [t.mean for t in seen]
        covs = [t.cov for t in seen]
        xy = np.array([m[[0, 2]] for m in means])
        # the positions' distance is at most the states' (a marginal of the same test): pairs
        # within the threshold's reach in position hold every close pair
        threshold = coalesce_d2(len(means[0]))
        reach2 = threshold * largest_xy_eigenvalue(np.array(covs))
        row = {t.track_id: k for k, t in enumerate(seen)}
        out: set[int] = set()
        tested: set[tuple[int, int]] = set()
        for i, j in close_pairs(xy, reach2):
            a, b = seen[i], seen[j]
            pair = (a.track_id, b.track_id)
            tested.add(pair)
            dx = means[i] - means[j]
            d2 = float(dx @ np.linalg.solve(covs[i] + covs[j], dx))
            count = self._close.get(pair, 0) + 1 if d2 <= threshold else 0
            self._count(pair, count)
            if count >= COALESCE_LOOKS:
                out.add(weaker(a, b).track_id)
        for pair in [p for p in self._close if p not in tested]:
            if pair[0] in row and pair[1] in row:  # both seen, out of reach: not close
                self._count(pair, 0)
        return sorted(out)


def weaker(a: Track, b: Track) -> Track:
    """Of two coalesced tracks, the one to delete: the lower probability of existence, then
    the lower fraction of hits per look, then the younger (the larger id)."""

    def support(t: Track) -> tuple[float, float, int]:
        return (t.existence, t.hits / max(t.looks, 1), -t.track_id)

    return a if support(a) < support(b) else b
