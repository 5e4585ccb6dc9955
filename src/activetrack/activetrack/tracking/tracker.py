"""The tracker: one filter per track (any registered one), fed with the epoch's scans.

One call of :meth:`Tracker.step` per epoch, with all of the epoch's scans, in the scenario's
sensor order:

1. every scan is checked first (sensor, epoch, time, shapes, finiteness); a bad one raises
   ValueError naming the field and leaves the tracker untouched (no track, no draw);
2. every track's filter predicts to the epoch's time (its motion model);
3. the scans update the tracks, by the scene's association:

   - **known** (one target, known to exist from epoch 0 on, and no clutter): the track's
     filter takes the epoch's scans as its measurements, a scan without a detection as
     "looked, saw nothing" (``filter.step``; Hernandez sec. 2.3, the papers' tracking);
   - **JPDA** (several targets, births or clutter): each scan in turn updates the tracks whose
     predicted position is inside its field of view (found through a k-d tree of the predicted
     positions, :class:`.spatial.FovIndex`, then tested exactly): the chi-square gate ``gamma
     = gate_sigmas^2`` on each track's predicted measurement (its filter's moments, linearised
     at the mean), the likelihood ratios and the JPDA marginals ``beta`` (Bar-Shalom, Daum &
     Huang 2009; :func:`activetrack.filters.jpda.jpda_probabilities`) per cluster of tracks
     that share gated detections (exact: the joint events factorise over clusters; each
     cluster whole, never split); each track's filter takes its row of ``beta``
     (``update_pda``). The predicted measurements and gate are computed once per scan.
     Particle tracks (``particle_based`` filters) take the Monte Carlo JPDAF
     (:mod:`activetrack.filters.jpda_particle`): their likelihood ratios are their particles'
     estimates of the predicted likelihood, the same enumeration gives ``beta``, and each
     gated pair's per-particle likelihoods go to the filter's weight update (computed once).
     Zero clutter and ``Pd = 1`` go through the floor and cap of
     :mod:`activetrack.filters.clutter_likelihood`. A cluster too large for its exact JPDA
     (a hypothesis net beyond ``max_edges``: hundreds of tentative tracks from heavy clutter,
     chained through shared detections) raises :class:`NetOversize` naming
     ``tracker.tracks.oversize_cluster`` (``error``, the default), or (``prune``) loses its
     weakest gated pairs until it fits, then takes the exact JPDA of the pruned gate
     (:mod:`activetrack.filters.jpda_prune`, a gating approximation), each pruned cluster and
     dropped pair counted (:attr:`Tracker.counters`), with one warning per run. The same
     likelihood ratios first give
     each track's existence its LM-IPDA update, with Pd times the probability that the target
     lies in the scan's sector. Detections no track gated start tentative tracks at once where
     the sensor fixes a position from one (:meth:`Tracker._start_from_detections`). Then M-of-N
     confirmation, existence, deletion and coalescence (:mod:`.management`).

Tracks from the priors of the targets present at epoch 0 start confirmed, ids 1, 2, ... in
scenario order; later tracks take the next id; ids are never reused. The tracker draws only
from its ``rng``: the filters' own draws (particles, resampling) and the planner's samples.
"""

from __future__ import annotations

import inspect
import logging
import math
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from activetrack import limits
from activetrack.arraytypes import BoolArray, FloatArray
from activetrack.data import CONFIRMED, TENTATIVE, Scan, TrackEstimate, TrackSet
from activetrack.filters.clutter_likelihood import effective_clutter_density, effective_pd
from activetrack.filters.jpda import (
    DEFAULT_MAX_EDGES,
    NetOversize,
    Pruning,
    gate_probability,
    jpda_probabilities,
    likelihood_ratios,
    pda_nis,
    predict_measurements,
)
from activetrack.filters.jpda_net import GateClusters
from activetrack.filters.jpda_particle import ParticleLikelihoods, particle_likelihoods
from activetrack.filters.measurement import TIME_TOLERANCE, Measurement, TrackingFilter
from activetrack.filters.resampling import systematic_resample
from activetrack.metrics import GospaWeights, gospa_reported, position_spread
from activetrack.models.base import MotionModel
from activetrack.models.clutter import ClutteredSensor
from activetrack.tracking.management import (
    EXISTENCE_INIT,
    Track,
    TrackManagementConfig,
    TrackManager,
    existence_update,
)
from activetrack.tracking.spatial import FovIndex

__all__ = ["OVERSIZE_FIELD", "FilterSpec", "NetOversize", "TrackPrior", "Tracker"]

OVERSIZE_FIELD = "tracker.tracks.oversize_cluster"  # the scenario field of the choice

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FilterSpec:
    """The tracker's filter: its registered ``kind``, whether its posterior is a particle set
    (``particle_based``: the planner gets samples of it) and ``make(x0, P0, t0)``, a new
    filter from a Gaussian in the model's state at time ``t0`` (drawing from the tracker's
    generator)."""

    kind: str
    particle_based: bool
    make: Callable[[FloatArray, FloatArray, float], TrackingFilter]
    # optional: k new filters at once from (k, n) means and (k, n, n) covariances (the filters
    # make would give, in order; drawing nothing from the generator)
    make_many: Callable[[FloatArray, FloatArray, float], Sequence[TrackingFilter]] | None = None


@dataclass(frozen=True)
class TrackPrior:
    """A target present at epoch 0: its id, prior ``mean`` ``(n,)`` and ``cov`` ``(n, n)`` in
    the model's state, and its planner ``priority``."""

    target_id: str
    mean: FloatArray
    cov: FloatArray
    priority: float = 1.0


@dataclass(frozen=True)
class _Checked:
    """A scan that passed the checks: its sensor, detections ``(m, dim_z)`` and pv ``(4,)``."""

    scan: Scan
    sensor: ClutteredSensor
    Z: FloatArray
    s: FloatArray


class Tracker:
    """The tracks of a scene (module docstring): the filters' motion ``model`` (``motion_name``
    its scenario name), the ``filter`` run per track, the scene's ``sensors`` by id in scenario
    order, the ``priors`` of the targets present at epoch 0, JPDA with ``management`` unless
    ``known_association``, ``planner_samples`` per particle track, and ``rng``, the tracker's
    only source of randomness; ``report``: the GOSPA weights by which confirmed tracks are
    withheld from the estimate (:func:`activetrack.metrics.gospa_reported`; None: none is)."""

    def __init__(
        self,
        model: MotionModel,
        motion_name: str,
        filter: FilterSpec,
        sensors: Mapping[str, ClutteredSensor],
        priors: Sequence[TrackPrior],
        *,
        known_association: bool,
        management: TrackManagementConfig,
        planner_samples: int,
        new_track_priority: float,
        rng: np.random.Generator,
        report: GospaWeights | None = None,
    ):
        if known_association and len(priors) != 1:
            raise ValueError(
                f"priors: known association tracks exactly one target, got {len(priors)}"
            )
        self.model = model
        self.motion_name = motion_name
        self.filter = filter
        self.sensors = dict(sensors)
        self.known_association = known_association
        self.planner_samples = planner_samples
        self.new_track_priority = new_track_priority
        self.rng = rng
        self.report = report
        self.survival = management.existence_survival
        self.gamma = management.gate_sigmas**2
        self.oversize = management.oversize_cluster
        self.pruning = Pruning()  # oversize clusters pruned, pairs dropped (oversize "prune")
        self.max_edges = DEFAULT_MAX_EDGES  # a cluster's net memory bound (jpda_net)
        self.book = TrackManager(management)
        self.epoch = 0
        self.time = 0.0
        self.updates = 0
        self._counts = (0, 0)  # detections, unassociated of the last step
        self._aged: set[int] = set()  # tracks whose existence was predicted this epoch
        self._stacked: type | None = None  # the live filters' class if it reads stacked moments
        for prior in priors:
            self._start(prior.mean, prior.cov, 0, CONFIRMED, prior.target_id, prior.priority)
        self._draw_samples()

    # --- the epoch ---------------------------------------------------------------------------
    def step(self, epoch: int, t: float, scans: Sequence[Scan]) -> TrackSet:
        """Predict to ``t``, update with the epoch's ``scans``, manage the tracks; the
        :class:`TrackSet` after it. ValueError (state unchanged) for a bad scan;
        :class:`NetOversize` (``oversize_cluster: error``) part-way: the epoch is left
        unfinished (its earlier scans applied, no track management, the epoch not taken),
        and a later epoch may still be stepped."""
        t, checked = self._check(epoch, t, scans)
        if self.known_association:
            detections = self._step_known(t, checked)
            unassociated = 0
        else:
            detections, unassociated = self._step_jpda(epoch, t, checked)
        self.epoch, self.time = epoch, t
        self.updates += 1
        self._counts = (detections, unassociated)
        self._draw_samples()
        return self.snapshot()

    def snapshot(self) -> TrackSet:
        """Every live track after the last step, by id. Pure: it draws nothing, so looking at
        the tracks (a notebook, a second caller) never changes a later result."""
        live = self.book.live()
        if self._stacked is not None and self.model.state_is_pv:  # the moments read stacked
            X, P = self._pv_means(live), self._pv_covs(live)
            moments = zip(X, P, X.copy(), P.copy(), strict=True)
            estimates = tuple(
                track.estimate(self.epoch, m) for track, m in zip(live, moments, strict=True)
            )
        else:
            estimates = tuple(track.estimate(self.epoch) for track in live)
        if self.report is not None:
            estimates = self._withhold(estimates)
        return TrackSet(
            self.epoch,
            self.time,
            self.filter.kind,
            self.motion_name,
            tuple(self.model.state_names),
            estimates,
            self.updates,
            *self._counts,
        )

    def _withhold(self, estimates: tuple[TrackEstimate, ...]) -> tuple[TrackEstimate, ...]:
        """The confirmed estimates whose reporting would raise their expected GOSPA marked
        ``withheld`` (:func:`activetrack.metrics.gospa_reported` with ``self.report``)."""
        assert self.report is not None
        confirmed = [i for i, e in enumerate(estimates) if e.confirmed]
        if not confirmed:
            return estimates
        r = np.array([estimates[i].existence for i in confirmed])
        spread = position_spread(np.stack([estimates[i].cov for i in confirmed]))
        keep = gospa_reported(r, spread, self.report)
        out = list(estimates)
        for i, reported in zip(confirmed, keep, strict=True):
            if not reported:
                out[i] = replace(out[i], withheld=True)
        return tuple(out)

    @property
    def not_started(self) -> int:
        """Detections that would have started a track beyond ``max_tracks``."""
        return self.book.not_started

    @property
    def counters(self) -> Counter[str]:
        """What the tracker did that changes its result: deletions by reason, detections not
        started (``max_tracks`` reached), JPDA clusters pruned and gated pairs dropped from
        them (``oversize_cluster: prune``)."""
        out = Counter({f"deleted.{k}": v for k, v in self.book.deleted.items()})
        out["not_started"] = self.book.not_started
        out.update(self.association_counters)
        return out

    @property
    def association_counters(self) -> dict[str, int]:
        """``association.pruned_clusters`` and ``association.dropped_pairs`` so far: what the
        ``prune`` approximation did (both 0 while every cluster's exact JPDA fits)."""
        return {
            "association.pruned_clusters": self.pruning.clusters,
            "association.dropped_pairs": self.pruning.pairs,
        }

    # --- known association: the papers' single target -----------------------------------------
    def _step_known(self, t: float, checked: list[_Checked]) -> int:
        """The one track's filter on the epoch's scans (module docstring)."""
        track = self.book.live()[0]
        measurements = []
        for i, c in enumerate(checked):
            if c.Z.shape[0] > 1:
                raise ValueError(
                    f"scans[{i}].Z: a scene of one target without clutter has at most one "
                    f"detection per scan, got {c.Z.shape[0]}"
                )
            z = c.Z[0] if c.Z.shape[0] else None
            measurements.append(Measurement(c.sensor.base, c.s, z, t, c.scan.sensor_id))
        info = track.filter.step(t, measurements)
        if checked:
            track.looks += 1
            track.hits += info.n_detections > 0
        track.missed_detections += info.n_missed
        track.nis, track.ess = info.nis, info.ess
        return info.n_detections

    # --- JPDA ----------------------------------------------------------------------------------
    def _step_jpda(self, epoch: int, t: float, checked: list[_Checked]) -> tuple[int, int]:
        live = self.book.live()
        filters = [track.filter for track in live]
        classes = {type(f) for f in filters}
        cls = classes.pop() if len(classes) == 1 else None
        if cls and _has_many(cls, "predict"):  # the EKF: all tracks at once
            cls.predict_many(filters, t)  # type: ignore[attr-defined]
        else:
            for f in filters:
                f.predict(t)
        for track in live:  # this epoch's updates set it (pda_nis)
            track.nis = math.nan
        self._aged.clear()
        # The filters' class when it reads many filters' moments at once (the EKF), else None
        self._stacked = cls if cls and _has_many(cls, "mean", "means_many") else None
        # The predicted positions, indexed once: each scan tests only the tracks within reach.
        index = FovIndex(live, self._pv_means(live).reshape(-1, 4)[:, [0, 2]])
        looked: dict[int, bool] = {}  # track id -> hit, for the tracks looked at
        detections = unassociated = 0
        for c in checked:
            tracks, mask = self._update(c, t, index)
            hits: list[bool] = np.asarray(mask.any(axis=1)).tolist()
            for track, hit in zip(tracks, hits, strict=True):
                looked[track.track_id] = looked.get(track.track_id, False) or hit
                track.missed_detections += not hit
            free = ~mask.any(axis=0)
            detections += c.Z.shape[0]
            unassociated += int(free.sum())
            started = self._start_from_detections(c.Z[free], c, epoch, t)
            for track in started:
                looked[track.track_id] = True
                if type(track.filter) is not self._stacked:  # a new class: read one by one
                    self._stacked = None
            for track, xy in zip(started, self._pv_means(started).reshape(-1, 4), strict=True):
                index.add(track, xy[[0, 2]])
        self.book.end_epoch(looked, self._pv_covs)
        return detections, unassociated

    def _update(self, c: _Checked, t: float, index: FovIndex) -> tuple[list[Track], BoolArray]:
        """Update the tracks inside the scan's field of view; them and their gate ``(T, m)``.
        The predicted measurements, Jacobians, residuals and gate are computed once here, for
        the existence update, the JPDA and the EKF updates alike."""
        candidates: list[Track] = index.candidates(c.scan.fov, c.s)  # type: ignore[assignment]
        pv_state = self.model.state_is_pv  # pv = the state: read each filter's moments once
        pv = self._pv_means(candidates).reshape(-1, 4)
        inside = c.scan.fov.contains(pv, c.s)
        tracks = [track for track, ok in zip(candidates, inside, strict=True) if ok]
        if not tracks:
            return [], np.zeros((0, c.Z.shape[0]), dtype=bool)
        means = pv[inside] if pv_state else np.array([track.state for track in tracks])
        if self._stacked is not None:
            covs = self._stacked.covs_many([track.filter for track in tracks])  # type: ignore[attr-defined]
        else:
            covs = np.array([track.state_cov for track in tracks])
        base = c.sensor.base
        zhat, H, S = predict_measurements(means, covs, base, c.s, self.model)
        nu = np.asarray(base.residual(c.Z[None, :, :], zhat[:, None, :]), dtype=float)
        lam = effective_clutter_density(c.sensor.clutter_density)
        pd = effective_pd(c.sensor.pd)
        ratios, mask = likelihood_ratios(nu, S, 1.0, lam, self.gamma)
        particles = None
        if self.filter.particle_based:  # the MC-JPDAF: each track's particles give its ratios
            posteriors = [track.filter for track in tracks]
            particles = particle_likelihoods(
                posteriors,  # type: ignore[arg-type]
                c.Z,
                base,
                c.s,
                self.model,
                gated=mask,
            )
            ratios = particles.ratios(1.0, lam)
        for track in tracks:
            if track.track_id not in self._aged:
                track.existence *= self.survival
                self._aged.add(track.track_id)
        pv_means = pv[inside]
        pv_covs = covs if pv_state else np.array([track.cov for track in tracks])
        psi = existence_update(
            np.array([track.existence for track in tracks]),
            ratios,
            pd * c.scan.fov.coverage(pv_means, pv_covs, c.s),
            gate_probability(self.gamma, int(base.dim_z)),
        )
        for track, p in zip(tracks, psi, strict=True):
            track.existence = float(p)
        self._jpda(tracks, H, nu, S, particles, mask, c, t)
        updated = [tracks[row] for row in np.flatnonzero(mask.any(axis=1))]
        index.moved_many(updated, self._pv_means(updated).reshape(-1, 4)[:, [0, 2]])
        return tracks, mask

    def _pv_means(self, tracks: Sequence[Track]) -> FloatArray:
        """The tracks' pv means ``(T, 4)``: their filters' means stacked in one call where the
        state is pv and the filters read stacked (``means_many``), else each track's."""
        if self.model.state_is_pv and self._stacked is not None:
            return self._stacked.means_many([t.filter for t in tracks])  # type: ignore[attr-defined]
        return np.array([track.mean for track in tracks], dtype=float)

    def _pv_covs(self, tracks: Sequence[Track]) -> FloatArray:
        """The tracks' pv covariances ``(T, 4, 4)``, stacked as :meth:`_pv_means`."""
        if self.model.state_is_pv and self._stacked is not None:
            return self._stacked.covs_many([t.filter for t in tracks])  # type: ignore[attr-defined]
        return np.array([track.cov for track in tracks], dtype=float).reshape(-1, 4, 4)

    def _jpda(
        self,
        tracks: list[Track],
        H: FloatArray,
        nu: FloatArray,
        S: FloatArray,
        particles: ParticleLikelihoods | None,
        mask: BoolArray,
        c: _Checked,
        t: float,
    ) -> None:
        """The JPDA marginals per cluster (exact, the whole cluster at once); each track's
        filter takes its row of them. Particle tracks: from their ``particles``' likelihoods
        (the MC-JPDAF, :mod:`activetrack.filters.jpda_particle`), Gaussian ones from the scan's
        Jacobians ``H`` ``(T, d, n)``, residuals ``nu`` ``(T, m, d)`` and ``S`` ``(T, d, d)``
        (a filter whose ``update_pda`` takes ``linearization`` is given its ``H`` and ``nu``).
        A cluster's ratios are taken from its own pairs (:func:`_cluster_ratios`)."""
        pd = effective_pd(c.sensor.pd)
        pg = gate_probability(self.gamma, int(c.sensor.base.dim_z))
        lam = effective_clutter_density(c.sensor.clutter_density)
        gate = GateClusters(mask)  # clustered once: the updates and the marginals alike
        clusters = _clusters(gate)
        by_size = _by_size(clusters)
        if particles is None:  # each cluster's ratios from its own pairs, in one scan matrix
            scan_ratios = _cluster_ratios(by_size, nu, S, pd, lam, self.gamma, mask.shape)
        else:
            scan_ratios = particles.ratios(pd, lam)
        # One call for the scan, on the gate's clusters (split where a ratio is 0): each
        # cluster's marginals as a call on that cluster alone would give (tested to the bit).
        scan_beta = self._marginals(scan_ratios, pd, pg, gate, c)
        if particles is None:  # the last update's NIS of each Gaussian track it moved
            for track, nis in zip(tracks, pda_nis(nu, S, scan_beta).tolist(), strict=True):
                if not math.isnan(nis):
                    track.nis = nis
        R = c.sensor.base.R
        stacked = self._stacked
        if particles is None and stacked is not None and _has_many(stacked, "update_pda"):
            _update_stacked(stacked, tracks, H, nu, scan_beta, by_size, R, c.scan.sensor_id)
            return
        # EKF-like tracks (a class with update_pda_many) by class and detections: one stacked
        # update per group after the clusters (each track's update is its own)
        batches: dict[tuple[type, int], list[tuple[int, np.ndarray, FloatArray]]] = {}
        for rows, used in clusters:
            beta = scan_beta[rows[:, None], np.concatenate(([0], used + 1))]
            detections: list[Measurement] | None = None
            for k, row in enumerate(rows):
                cls = type(tracks[row].filter)
                if particles is None and _has_many(cls, "update_pda"):
                    batches.setdefault((cls, used.size), []).append((row, used, beta[k]))
                    continue
                if detections is None:
                    detections = [
                        Measurement(c.sensor.base, c.s, z, t, c.scan.sensor_id) for z in c.Z[used]
                    ]
                update = tracks[row].filter.update_pda
                if particles is not None and _takes(update, "log_likelihoods"):
                    # reuse g(z_j | x_i), computed once a scan
                    ell = [particles.ell[row][j] for j in used]
                    info = update(detections, beta[k], log_likelihoods=ell)
                elif particles is None and _takes(update, "linearization"):
                    info = update(detections, beta[k], linearization=(H[row], nu[row, used]))
                else:
                    info = update(detections, beta[k])
                tracks[row].ess = info.ess
        for (cls, _), group in batches.items():
            rows = np.array([row for row, _, _ in group])
            cols = np.array([used for _, used, _ in group])
            beta = np.array([b for _, _, b in group])
            _pda_many(cls, tracks, rows, cols, beta, H, nu, R, c.scan.sensor_id)

    def _marginals(
        self, ratios: FloatArray, pd: float, pg: float, gate: GateClusters, c: _Checked
    ) -> FloatArray:
        """The scan's JPDA marginals, an oversize cluster handled as ``oversize_cluster``
        says (module docstring): NetOversize naming the field, or pruned, counted and warned
        once per run."""
        before = self.pruning.clusters
        try:
            beta = jpda_probabilities(
                ratios,
                pd,
                pg,
                max_edges=self.max_edges,
                clusters=gate,
                oversize=self.oversize,
                pruning=self.pruning,
            )
        except NetOversize as e:
            if self.oversize != "error":
                raise
            raise NetOversize(
                f"{OVERSIZE_FIELD}: error (exact JPDA everywhere) at epoch {c.scan.epoch}, "
                f"scan of {c.scan.sensor_id!r}: {e}; or set {OVERSIZE_FIELD}: prune to drop "
                "such a cluster's weakest gated pairs until it fits (counted in "
                "association.pruned_clusters and association.dropped_pairs)",
                tracks=e.tracks,
                measurements=e.measurements,
                pairs=e.pairs,
                max_edges=e.max_edges,
            ) from None
        if before == 0 and self.pruning.clusters:
            _log.warning(
                "%s: prune: a JPDA cluster too large for its exact hypothesis net at epoch %d "
                "(scan of %r) lost its weakest gated pairs (each pruned cluster and dropped "
                "pair counted in association.pruned_clusters and association.dropped_pairs; "
                "this warning once per run)",
                OVERSIZE_FIELD,
                c.scan.epoch,
                c.scan.sensor_id,
            )
        return beta

    # --- track starts ------------------------------------------------------------------------
    def _start(
        self,
        mean: FloatArray,
        cov: FloatArray,
        born: int,
        status: str,
        origin: str,
        priority: float,
        t: float = 0.0,
    ) -> Track:
        """A new track with the next id: a filter started from N(mean, cov) at time ``t``."""
        new = self.filter.make(np.asarray(mean, dtype=float), np.asarray(cov, dtype=float), t)
        return self._track(new, born, status, origin, priority)

    def _track(
        self, new: TrackingFilter, born: int, status: str, origin: str, priority: float
    ) -> Track:
        """A new track of the filter ``new`` with the next id."""
        track = Track(
            self.book.new_id(),
            status,
            new,
            self.model,
            born,
            origin,
            priority,
            self.filter.particle_based,
        )
        self.book.add(track)
        return track

    def _start_from_detections(
        self, Z: FloatArray, c: _Checked, epoch: int, t: float
    ) -> list[Track]:
        """Tentative tracks at the positions the detections ``Z`` ``(k, dim_z)`` fix (the
        sensor's ``inverse_position``: a range-bearing radar does, a bearing sensor does not),
        velocity 0, covariance ``J R J^T`` and ``init_speed_std^2``, in order, while the tracker
        holds fewer than ``max_tracks`` (each detection beyond counted in ``not_started``,
        with one warning per run); none if the tracker does not initiate."""
        if not self.book.cfg.initiate or Z.shape[0] == 0:
            return []
        fixes = [f for f in (c.sensor.base.inverse_position(z, c.s) for z in Z) if f is not None]
        room = max(self.book.cfg.max_tracks - len(self.book.tracks), 0)
        if len(fixes) > room:
            if not self.book.not_started:  # once per run; every one is counted
                _log.warning(
                    "tracker.tracks.max_tracks=%d reached at epoch %d: a detection that would "
                    "start a track beyond it starts none (each counted in not_started; this "
                    "warning once per run)",
                    self.book.cfg.max_tracks,
                    epoch,
                )
            self.book.not_started += len(fixes) - room
            fixes = fixes[:room]
        if not fixes:
            return []
        means = np.zeros((len(fixes), 4))
        velocity = np.diag(np.full(4, self.book.cfg.init_speed_std**2))
        covs = np.array([velocity] * len(fixes))
        xy = np.array([f[0] for f in fixes], dtype=float).reshape(-1, 2)
        P_xy = np.array([f[1] for f in fixes], dtype=float).reshape(-1, 2, 2)
        means[:, 0], means[:, 2] = xy[:, 0], xy[:, 1]
        covs[:, 0, 0], covs[:, 0, 2] = P_xy[:, 0, 0], P_xy[:, 0, 1]
        covs[:, 2, 0], covs[:, 2, 2] = P_xy[:, 1, 0], P_xy[:, 1, 1]
        make_many = self.filter.make_many
        if make_many is None:
            filters = [self.filter.make(means[k], covs[k], t) for k in range(len(fixes))]
        else:
            filters = list(make_many(means, covs, t))
        out = []
        for new in filters:
            track = self._track(new, epoch, TENTATIVE, "", self.new_track_priority)
            track.existence = EXISTENCE_INIT
            out.append(track)
        return out

    def _draw_samples(self) -> None:
        """The planner's equally weighted samples of every particle track: a systematic
        resample of its weighted particles, thinned evenly to ``planner_samples``."""
        if not self.filter.particle_based:
            return
        for track in self.book.live():
            posterior = track.filter
            weights = posterior.weights  # type: ignore[attr-defined]
            count = len(weights)
            idx = systematic_resample(weights, self.rng)
            take = np.linspace(0, count - 1, min(self.planner_samples, count)).astype(int)
            track.samples = posterior.particles[idx[take]]  # type: ignore[attr-defined]

    # --- checks ------------------------------------------------------------------------------
    def _check(self, epoch: int, t: float, scans: Sequence[Scan]) -> tuple[float, list[_Checked]]:
        """Every scan checked before anything changes: ``(t, checked scans)``."""
        if (
            isinstance(epoch, bool)
            or not isinstance(epoch, int | np.integer)
            or epoch <= self.epoch
        ):
            raise ValueError(
                f"epoch: must be an integer > the last epoch {self.epoch}, got {epoch!r}"
            )
        t = float(t)
        if not (math.isfinite(t) and t >= self.time - TIME_TOLERANCE):
            raise ValueError(f"t: must be finite and >= the last time {self.time}, got {t!r}")
        out: list[_Checked] = []
        for i, scan in enumerate(scans):
            sensor = self.sensors.get(scan.sensor_id)
            if sensor is None:
                raise ValueError(
                    f"scans[{i}].sensor_id: must be one of {sorted(self.sensors)}, "
                    f"got {scan.sensor_id!r}"
                )
            if any(c.scan.sensor_id == scan.sensor_id for c in out):
                raise ValueError(f"scans[{i}].sensor_id: {scan.sensor_id!r} has two scans")
            if scan.epoch != epoch:
                raise ValueError(f"scans[{i}].epoch: must be {epoch}, got {scan.epoch!r}")
            if not abs(float(scan.time) - t) <= TIME_TOLERANCE:
                raise ValueError(f"scans[{i}].time: must equal t = {t}, got {scan.time!r}")
            out.append(_Checked(scan, sensor, _detections(i, scan, sensor), _platform(i, scan)))
        return max(t, self.time), out


def _detections(i: int, scan: Scan, sensor: ClutteredSensor) -> FloatArray:
    """The scan's detections as ``(m, dim_z)``, checked (an empty array of any shape: m = 0)."""
    d = int(sensor.base.dim_z)
    Z = np.asarray(scan.Z, dtype=float)
    if Z.size == 0 and Z.ndim in (1, 2):
        return np.zeros((0, d))
    if Z.ndim != 2 or Z.shape[1] != d:
        raise ValueError(f"scans[{i}].Z: must have shape (m, {d}), got {Z.shape}")
    if Z.shape[0] > limits.MAX_SCAN_DETECTIONS:
        raise ValueError(
            f"scans[{i}].Z: at most {limits.MAX_SCAN_DETECTIONS} detections per scan "
            f"(limits.MAX_SCAN_DETECTIONS), got {Z.shape[0]}"
        )
    if not np.isfinite(Z).all():
        raise ValueError(f"scans[{i}].Z: must be finite (no NaN or inf)")
    return Z


def _platform(i: int, scan: Scan) -> FloatArray:
    s = np.asarray(scan.sensor_pv, dtype=float)
    if s.shape != (4,) or not np.isfinite(s).all():
        raise ValueError(f"scans[{i}].sensor_pv: must be a finite pv of shape (4,), got {s!r}")
    return s


def _has_many(cls: type, method: str, batch: str = "") -> bool:
    """Whether filter class ``cls`` has ``batch`` (default ``<method>_many``), the batch form
    of ``method``, from the same class as its ``method`` (a subclass that overrides ``method``
    alone keeps it). ``mean`` (its batch ``means_many``) stands for the moments, ``mean``
    and ``cov``: both must come from that class."""
    batch = batch or method + "_many"
    known = _HAS_MANY.get((cls, batch))
    if known is None:

        def owner(name: str) -> type | None:
            return next((c for c in cls.__mro__ if name in c.__dict__), None)

        many = owner(batch)
        known = many is not None and many is owner(method)
        if method == "mean":
            known = known and owner("covs_many") is many is owner("cov")
        _HAS_MANY[cls, batch] = known
    return known


_HAS_MANY: dict[tuple[type, str], bool] = {}


def _takes(update: Callable[..., object], keyword: str) -> bool:
    """Whether a filter's ``update_pda`` takes ``keyword``: precomputed ``log_likelihoods``
    (the built-in particle filter) or ``linearization`` (the built-in EKF); a plugin's may
    take neither."""
    func = getattr(update, "__func__", update)
    known = _TAKES.get((func, keyword))
    if known is None:
        try:
            known = keyword in inspect.signature(update).parameters
        except (TypeError, ValueError):  # a callable without a signature
            known = False
        _TAKES[func, keyword] = known
    return known


_TAKES: dict[tuple[object, str], bool] = {}


def _update_stacked(
    cls: type,
    tracks: list[Track],
    H: FloatArray,
    nu: FloatArray,
    scan_beta: FloatArray,
    by_size: dict[int, tuple[np.ndarray, np.ndarray]],
    R: FloatArray,
    sensor_id: str,
) -> None:
    """Every cluster's tracks, all of filter class ``cls``, updated with their rows of the
    scan's marginals ``(T, m + 1)``: one ``update_pda_many`` per cluster size (:func:`_by_size`),
    no loop per track."""
    for rows, cols in by_size.values():
        beta = scan_beta[rows[:, None], np.column_stack((np.zeros_like(rows), cols + 1))]
        _pda_many(cls, tracks, rows, cols, beta, H, nu, R, sensor_id)


def _pda_many(
    cls: type,
    tracks: list[Track],
    rows: np.ndarray,
    cols: np.ndarray,
    beta: FloatArray,
    H: FloatArray,
    nu: FloatArray,
    R: FloatArray,
    sensor_id: str,
) -> None:
    """One ``update_pda_many`` of the tracks ``rows`` ``(G,)`` (all of filter class ``cls``),
    each with its detections ``cols`` ``(G, m)`` and association probabilities ``beta``
    ``(G, m + 1)``; their ESS is NaN (no particles)."""
    cls.update_pda_many(  # type: ignore[attr-defined]
        [tracks[row].filter for row in rows], H[rows], nu[rows[:, None], cols], beta, R, sensor_id
    )
    for row in rows.tolist():
        tracks[row].ess = math.nan


def _by_size(
    clusters: list[tuple[np.ndarray, np.ndarray]],
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """The clusters by their number of detections ``m``: each group's tracks ``(R,)`` and each
    track's cluster detections ``(R, m)``, the clusters in order."""
    members: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    for rows, used in clusters:
        members.setdefault(used.size, []).append((rows, used))
    out = {}
    for m, group in members.items():
        rows = np.concatenate([rows for rows, _ in group])
        sizes = [rows.size for rows, _ in group]
        out[m] = (rows, np.repeat(np.array([used for _, used in group]).reshape(-1, m), sizes, 0))
    return out


def _cluster_ratios(
    by_size: dict[int, tuple[np.ndarray, np.ndarray]],
    nu: FloatArray,
    S: FloatArray,
    pd: float,
    clutter_density: float,
    gamma: float,
    shape: tuple[int, int],
) -> FloatArray:
    """The scan's likelihood ratios ``shape`` ``(T, m)``, each cluster's (:func:`_by_size`)
    from its own pairs as :func:`~activetrack.filters.jpda.likelihood_ratios` of the cluster
    gives them, 0 elsewhere: LAPACK's solve for ``S^-1 nu`` rounds a column differently with
    other columns beside it (1 ulp), and these are the numbers of the per-cluster association
    the tracker has always run, to the bit. The clusters with the same number of detections go
    in one stacked call (a track's solve then has the same columns as in its cluster's own
    call)."""
    out = np.zeros(shape)
    for rows, cols in by_size.values():
        ratios, _ = likelihood_ratios(nu[rows[:, None], cols], S[rows], pd, clutter_density, gamma)
        out[rows[:, None], cols] = ratios
    return out


def _clusters(gate: GateClusters) -> list[tuple[np.ndarray, np.ndarray]]:
    """Tracks linked through shared gated detections: ``(rows, cols)`` per cluster, by their
    first row (tracks without a gated detection are in none). The JPDA's joint events
    factorise over them (:func:`~activetrack.filters.jpda_net.gate_clusters`)."""
    return [(rows, cols) for rows, cols in gate.clusters if cols.size]
