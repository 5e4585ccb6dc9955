"""Track state and M-of-N track management of the multi-target tracker.

A :class:`Track` is one Gaussian (JPDA-EKF) or one particle cloud (:class:`ParticleCloud`) with
its id, status and look history. :class:`TrackManager` holds the live tracks and applies the
rules of ``tracker.tracks`` (:class:`~activetrack.scenarios.multitarget_config.
TrackManagementConfig`) once per epoch (M-of-N confirmation and deletion: Blackman & Popoli,
*Design and Analysis of Modern Tracking Systems*, 1999):

- a **look** is an epoch at which at least one scan's field of view held the track's predicted
  position; a **hit** a look with at least one detection in the track's gate (any scan of the
  epoch). The detection that starts a track is its first look and hit;
- a tentative track is **confirmed** once it has ``confirm_m`` hits in its last ``confirm_n``
  looks. It is confirmed or deleted within its first ``confirm_n`` looks, so its last
  ``confirm_n`` looks are all of them: it is **deleted** as soon as
  ``hits + (confirm_n - looks) < confirm_m`` (it can no longer reach M);
- a confirmed track is deleted after ``delete_misses`` consecutive looks without a hit;
- any track is deleted when its position standard deviation (sqrt of the largest eigenvalue of
  its xy covariance block) exceeds ``max_position_std`` (lost: a planner cannot use it);
- **coalescence** (two JPDA tracks drawn onto one target, Fitzgerald 1985; Blom & Bloem 2000):
  two confirmed tracks whose positions are within Mahalanobis distance
  ``d^2 = dp^T (P_a + P_b)^-1 dp <= COALESCE_D2`` at ``COALESCE_LOOKS`` consecutive epochs at
  which both were looked at: the younger (the larger id: ids are given in order of creation)
  is deleted. Two tracks on two targets that cross pass through that distance for an epoch or
  two; tracks on one target stay there.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass, field

import numpy as np

from activetrack.arraytypes import FloatArray
from activetrack.filters.resampling import effective_sample_size, roughen, systematic_resample
from activetrack.models.base import MotionModel
from activetrack.multitarget.data import CONFIRMED, TENTATIVE, TrackEstimate
from activetrack.scenarios.multitarget_config import TrackManagementConfig

__all__ = [
    "COALESCE_D2",
    "COALESCE_LOOKS",
    "ParticleCloud",
    "Track",
    "TrackManager",
    "position_std",
]

COALESCE_D2 = 0.5  # squared Mahalanobis distance of the two positions (2 dof: ~22 % quantile)
COALESCE_LOOKS = 5  # consecutive joint looks
_XY = np.ix_([0, 2], [0, 2])


def position_std(cov: FloatArray) -> float:
    """sqrt of the largest eigenvalue of the xy block of a pv covariance ``(4, 4)`` [m]."""
    return math.sqrt(max(float(np.linalg.eigvalsh(cov[_XY])[-1]), 0.0))


@dataclass
class ParticleCloud:
    """A weighted particle set: ``X`` ``(N, 4)`` pv particles, normalised weights ``w``
    ``(N,)`` and ``ess`` of the last weighting (before resampling; N at the start)."""

    X: FloatArray
    w: FloatArray
    ess: float

    @classmethod
    def draw(
        cls, mean: FloatArray, cov: FloatArray, n: int, rng: np.random.Generator
    ) -> ParticleCloud:
        """``n`` equally weighted draws from ``N(mean, cov)``."""
        X = mean + rng.standard_normal((n, mean.shape[0])) @ np.linalg.cholesky(cov).T
        return cls(X, np.full(n, 1.0 / n), float(n))

    def moments(self) -> tuple[FloatArray, FloatArray]:
        """Weighted mean ``(4,)`` and covariance ``(4, 4)``."""
        mean = self.w @ self.X
        D = self.X - mean
        P = (D.T * self.w) @ D
        return mean, 0.5 * (P + P.T)

    def predict(self, model: MotionModel, dt: float, rng: np.random.Generator) -> None:
        """Draw every particle from the transition prior over ``dt`` (the bootstrap proposal)."""
        if dt > 0.0:
            self.X = np.asarray(model.sample(self.X, dt, rng), dtype=float)

    def weigh(self, log_likelihood: FloatArray) -> bool:
        """Multiply the weights by ``exp(log_likelihood)`` ``(N,)`` (log-sum-exp normalised).
        False, weights unchanged, when no particle has a positive finite weight (collapse)."""
        with np.errstate(divide="ignore"):
            logw = np.log(self.w) + log_likelihood
        logw = np.where(np.isnan(logw), -math.inf, logw)
        top = float(np.max(logw))
        if not math.isfinite(top):
            return False
        w = np.exp(logw - top)
        self.w = w / w.sum()
        self.ess = effective_sample_size(self.w)
        return True

    def resample_if_due(
        self, mode: str, ess_threshold: float, roughening: float, rng: np.random.Generator
    ) -> None:
        """Systematic resampling every time (``"always"``) or when ESS < threshold N
        (``"ess"``), then Gordon's roughening (:mod:`activetrack.filters.resampling`)."""
        N = self.w.shape[0]
        if mode == "always" or self.ess < ess_threshold * N:
            self.X = np.take(self.X, systematic_resample(self.w, rng), axis=0)
            roughen(self.X, roughening, rng)
            self.w = np.full(N, 1.0 / N)

    def samples(self, count: int, rng: np.random.Generator) -> FloatArray:
        """``min(count, N)`` equally weighted samples: a systematic resample, thinned evenly."""
        idx = systematic_resample(self.w, rng)
        take = np.linspace(0, idx.shape[0] - 1, min(count, idx.shape[0])).astype(int)
        return self.X[idx[take]]


@dataclass
class Track:
    """One track: pv ``mean`` ``(4,)`` and ``cov`` ``(4, 4)`` (for a particle track the
    cloud's moments, kept in step by :meth:`sync`), status, and its M-of-N history."""

    track_id: int
    status: str
    mean: FloatArray
    cov: FloatArray
    born: int  # epoch it was started
    origin: str = ""
    priority: float = 1.0
    cloud: ParticleCloud | None = None
    looks: int = 0
    hits: int = 0
    run_of_misses: int = 0
    window: deque[bool] = field(default_factory=deque)  # hit per look, the last confirm_n
    samples: FloatArray | None = None

    @property
    def confirmed(self) -> bool:
        return self.status == CONFIRMED

    def sync(self) -> None:
        """Mean and covariance from the particle cloud (no-op for a Gaussian track)."""
        if self.cloud is not None:
            self.mean, self.cov = self.cloud.moments()

    def record_look(self, hit: bool, cfg: TrackManagementConfig) -> None:
        """Count one look (hit or not) and confirm a tentative track that reached M of N."""
        self.looks += 1
        self.hits += hit
        self.run_of_misses = 0 if hit else self.run_of_misses + 1
        self.window.append(hit)
        while len(self.window) > cfg.confirm_n:
            self.window.popleft()
        if self.status == TENTATIVE and sum(self.window) >= cfg.confirm_m:
            self.status = CONFIRMED

    def deletion_reason(self, cfg: TrackManagementConfig) -> str | None:
        """Why the track must go ("unconfirmed", "misses", "position_std"), or None."""
        if self.status == TENTATIVE and self.hits + cfg.confirm_n - self.looks < cfg.confirm_m:
            return "unconfirmed"
        if self.status == CONFIRMED and self.run_of_misses >= cfg.delete_misses:
            return "misses"
        if position_std(self.cov) > cfg.max_position_std:
            return "position_std"
        return None

    def estimate(self, epoch: int) -> TrackEstimate:
        """The track as the tracker reports it."""
        return TrackEstimate(
            track_id=self.track_id,
            status=self.status,
            mean=self.mean.copy(),
            cov=self.cov.copy(),
            origin=self.origin,
            priority=self.priority,
            age=epoch - self.born,
            hits=self.hits,
            misses=self.looks - self.hits,
            ess=self.cloud.ess if self.cloud is not None else math.nan,
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
        self._close: dict[tuple[int, int], int] = {}  # confirmed pair -> joint close looks

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

    def end_epoch(self, looked: dict[int, bool]) -> None:
        """Apply one epoch's looks (track id -> hit) and every deletion rule."""
        for track_id, hit in looked.items():
            if track_id in self.tracks:
                self.tracks[track_id].record_look(hit, self.cfg)
        for track in self.live():
            reason = track.deletion_reason(self.cfg)
            if reason is not None:
                self._delete(track.track_id, reason)
        for track_id in self._coalesced(looked):
            self._delete(track_id, "coalesced")

    def _delete(self, track_id: int, reason: str) -> None:
        if self.tracks.pop(track_id, None) is not None:
            self.deleted[reason] += 1
        self._close = {pair: n for pair, n in self._close.items() if track_id not in pair}

    def _coalesced(self, looked: dict[int, bool]) -> list[int]:
        """Update the closeness count of every pair of confirmed tracks both looked at this
        epoch; the younger track of each pair that reached ``COALESCE_LOOKS``."""
        seen = [t for t in self.live() if t.confirmed and t.track_id in looked]
        out: set[int] = set()
        for i, a in enumerate(seen):
            for b in seen[i + 1 :]:
                pair = (a.track_id, b.track_id)
                dp = (a.mean - b.mean)[[0, 2]]
                d2 = float(dp @ np.linalg.solve(a.cov[_XY] + b.cov[_XY], dp))
                count = self._close.get(pair, 0) + 1 if d2 <= COALESCE_D2 else 0
                self._close[pair] = count
                if count >= COALESCE_LOOKS:
                    out.add(b.track_id)  # b has the larger id: the younger
        return sorted(out)
