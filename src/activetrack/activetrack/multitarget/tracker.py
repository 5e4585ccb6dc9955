"""The multi-target tracker: JPDA-EKF or clutter-aware particle filters, M-of-N management.

One call of :meth:`MultiTargetTracker.step` per epoch, with all of the epoch's scans:

1. every scan is checked first (sensor, epoch, time, shapes, finiteness); a bad one raises
   ValueError naming the field and leaves the tracker untouched (no track, no draw);
2. every track is predicted to the epoch's time with the linear NCV model (``F``, ``Q``);
3. each scan, in the order given, updates the tracks whose predicted position is inside its
   field of view (:meth:`FieldOfView.contains`):

   - ``tracker.filter: ekf``: JPDA (:func:`activetrack.filters.jpda.jpda_update`, Bar-Shalom,
     Daum & Huang 2009) over each cluster of tracks that share gated detections (exact: the
     joint events factorise over clusters); a cluster whose events could exceed
     :data:`~activetrack.filters.jpda.DEFAULT_MAX_EVENTS` falls back to one PDA per track;
   - ``tracker.filter: pf``: each track's particle cloud is weighed by the whole scan's
     clutter-aware likelihood (:func:`activetrack.filters.clutter_likelihood.
     scan_log_likelihood`: missed-detection term plus the Pd-weighted mixture over its gated
     detections), resampled once per epoch as ``tracker.resample`` says;

   the gate is the chi-square gate ``gamma = gate_sigmas^2`` of each track's predicted
   measurement (for a particle track, of its moments). Zero clutter and ``Pd = 1`` go through
   the floor and cap of :mod:`activetrack.filters.clutter_likelihood`. Before the update, the
   same predicted measurements give each track's probability of existence its LM-IPDA update
   (:func:`~activetrack.multitarget.tracks.existence_update`; once per epoch first its
   survival), with Pd times the probability that the target lies in the scan's bearing sector
   (a track at a beam's edge that brings no detection is not counted a full miss);
4. detections of a range-bearing scan that no track gated start tentative tracks at once (so a
   later scan of the epoch already updates them): position from the inverse measurement,
   velocity 0, covariance ``J R J^T`` (J = d position / d z) and ``init_speed_std^2``; at most
   ``max_tracks`` live tracks, the rest counted in ``not_started``. Bearing-only detections
   never start tracks (a bearing fixes no position): bearings-only targets are tracked from
   their priors;
5. M-of-N confirmation (and existence) and deletion and the coalescence rule (:mod:`.tracks`).

Tracks from the priors of the targets present at epoch 0 start confirmed, ids 1, 2, ... in
scenario order; later tracks take the next id; ids are never reused. The tracker draws only
from its ``rng``: particles, resampling, the planner's samples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from activetrack.arraytypes import BoolArray, FloatArray
from activetrack.filters.clutter_likelihood import (
    effective_clutter_density,
    effective_pd,
    scan_log_likelihood,
)
from activetrack.filters.jpda import (
    DEFAULT_MAX_EVENTS,
    gate_probability,
    jpda_update,
    likelihood_ratios,
    predict_measurements,
)
from activetrack.filters.measurement import TIME_TOLERANCE
from activetrack.models.base import as_linear
from activetrack.models.clutter import INITIATING_KINDS, ClutteredSensor
from activetrack.multitarget.data import CONFIRMED, TENTATIVE, FieldOfView, Scan, TrackSet
from activetrack.multitarget.tracks import (
    EXISTENCE_INIT,
    EXISTENCE_SURVIVAL,
    ParticleCloud,
    Track,
    TrackManager,
    existence_update,
)
from activetrack.planning.assignment import sector_coverage
from activetrack.scenarios.build import build_motion_model, build_scan_sensors
from activetrack.scenarios.schema import Scenario

__all__ = ["INITIATING_KINDS", "MultiTargetTracker"]

FILTERS = ("ekf", "pf")
_XY = np.ix_([0, 2], [0, 2])


@dataclass(frozen=True)
class _Checked:
    """A scan that passed the checks: its sensor, detections ``(m, dim_z)`` and pv ``(4,)``."""

    scan: Scan
    sensor: ClutteredSensor
    Z: FloatArray
    s: FloatArray


class MultiTargetTracker:
    """JPDA-EKF / clutter-aware PF tracks of a multi-target scenario (module docstring).

    scenario: a validated scenario (``targets:`` list, or one ``target:``);
    rng: the tracker's only source of randomness.
    ``sensors``: the scenario's sensors in clutter, by id; ``epoch`` and ``time`` of the last
    step (0, 0.0 before the first); ``book``: the live tracks and their bookkeeping.
    """

    def __init__(self, scenario: Scenario, rng: np.random.Generator):
        cfg = scenario.tracker
        if cfg.filter not in FILTERS:
            raise ValueError(f"tracker.filter: must be one of {FILTERS}, got {cfg.filter!r}")
        model = build_motion_model(cfg.motion or scenario.target.motion)
        if not (model.is_linear and model.state_is_pv):
            raise ValueError("tracker.motion: the multi-target tracker needs a linear pv model")
        self.model = as_linear(model)
        self.kind = cfg.filter
        self.options = cfg
        self.rng = rng
        self.gamma = cfg.tracks.gate_sigmas**2
        self.sensors: dict[str, ClutteredSensor] = {
            sid: m for sid, (_, m) in build_scan_sensors(scenario).items()
        }
        self.new_track_priority = scenario.planner.targets.new_track_priority
        self.book = TrackManager(cfg.tracks)
        self.epoch = 0
        self.time = 0.0
        self._counts = (0, 0)  # detections, unassociated of the last step
        self._aged: set[int] = set()  # tracks whose existence was predicted this epoch
        for target in scenario.targets or [scenario.target]:
            if target.birth == 0:
                mean = np.array(target.prior.mean, dtype=float)
                cov = np.array(target.prior.covariance(), dtype=float)
                self._start(mean, cov, 0, CONFIRMED, target.id, target.priority)
        self._draw_samples()

    # --- the epoch ---------------------------------------------------------------------------
    def step(self, epoch: int, t: float, scans: Sequence[Scan]) -> TrackSet:
        """Predict to ``t``, update with the epoch's ``scans``, manage the tracks; the
        :class:`TrackSet` after it. ValueError (state unchanged) for a bad scan."""
        t, checked = self._check(epoch, t, scans)
        self._predict(t)
        self._aged.clear()
        looked: dict[int, bool] = {}  # track id -> hit, for the tracks looked at
        weighed: set[int] = set()
        detections = unassociated = 0
        for c in checked:
            tracks, mask = self._update(c)
            for track, row in zip(tracks, mask, strict=True):
                looked[track.track_id] = looked.get(track.track_id, False) or bool(row.any())
                weighed.add(track.track_id)
            free = ~mask.any(axis=0)
            detections += c.Z.shape[0]
            unassociated += int(free.sum())
            if c.sensor.kind in INITIATING_KINDS:
                for z in c.Z[free]:
                    started = self._start_from_detection(z, c, epoch)
                    if started is not None:
                        looked[started.track_id] = True
        self._resample(weighed)
        self.book.end_epoch(looked)
        self.epoch, self.time = epoch, t
        self._counts = (detections, unassociated)
        self._draw_samples()
        return self.snapshot()

    def snapshot(self) -> TrackSet:
        """Every live track after the last step, by id. Pure: it draws nothing."""
        estimates = tuple(track.estimate(self.epoch) for track in self.book.live())
        return TrackSet(self.epoch, self.time, self.kind, estimates, *self._counts)

    @property
    def not_started(self) -> int:
        """Detections that would have started a track beyond ``max_tracks``."""
        return self.book.not_started

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

    # --- filtering ---------------------------------------------------------------------------
    def _predict(self, t: float) -> None:
        """Every track to time ``t``: ``F x``, ``F P F^T + Q`` or the particles' transition."""
        dt = t - self.time
        if dt <= 0.0:
            return
        F = self.model.transition_matrix(dt)
        Q = self.model.process_noise(dt)
        for track in self.book.live():
            if track.cloud is not None:
                track.cloud.predict(self.model, dt, self.rng)
                track.sync()
            else:
                track.mean = F @ track.mean
                P = F @ track.cov @ F.T + Q
                track.cov = 0.5 * (P + P.T)

    def _update(self, c: _Checked) -> tuple[list[Track], BoolArray]:
        """Update the tracks inside the scan's field of view; them and their gate ``(T, m)``."""
        live = self.book.live()
        inside = c.scan.fov.contains(np.array([t.mean for t in live]).reshape(-1, 4), c.s)
        tracks = [track for track, ok in zip(live, inside, strict=True) if ok]
        if not tracks:
            return [], np.zeros((0, c.Z.shape[0]), dtype=bool)
        means = np.array([track.mean for track in tracks])
        covs = np.array([track.cov for track in tracks])
        base = c.sensor.base
        zhat, _, S = predict_measurements(means, covs, base, c.s, self.model)
        nu = np.asarray(base.residual(c.Z[None, :, :], zhat[:, None, :]), dtype=float)
        ratios, mask = likelihood_ratios(
            nu, S, 1.0, effective_clutter_density(c.sensor.clutter_density), self.gamma
        )
        for track in tracks:
            if track.track_id not in self._aged:
                track.existence *= EXISTENCE_SURVIVAL
                self._aged.add(track.track_id)
        psi = existence_update(
            np.array([track.existence for track in tracks]),
            ratios,
            effective_pd(c.sensor.pd) * _fov_coverage(means, covs, c.scan.fov, c.s),
            gate_probability(self.gamma, int(base.dim_z)),
        )
        for track, p in zip(tracks, psi, strict=True):
            track.existence = float(p)
        if self.kind == "ekf":
            self._jpda(tracks, means, covs, mask, c)
        else:
            self._weigh(tracks, mask, c)
        return tracks, mask

    def _jpda(
        self, tracks: list[Track], means: FloatArray, covs: FloatArray, mask: BoolArray, c: _Checked
    ) -> None:
        """JPDA-EKF per cluster; tracks with no gated detection keep their prediction."""
        for rows, cols in _clusters(mask):
            events = float(np.prod(1.0 + mask[np.ix_(rows, cols)].sum(axis=1)))
            groups = (
                [rows] if events <= DEFAULT_MAX_EVENTS else [rows[[k]] for k in range(rows.size)]
            )
            for group in groups:
                used = cols[mask[np.ix_(group, cols)].any(axis=0)]
                result = jpda_update(
                    means[group],
                    covs[group],
                    c.Z[used],
                    c.sensor.base,
                    c.s,
                    self.model,
                    clutter_density=effective_clutter_density(c.sensor.clutter_density),
                    gamma=self.gamma,
                    pd=effective_pd(c.sensor.pd),
                )
                for k, row in enumerate(group):
                    tracks[row].mean, tracks[row].cov = result.means[k], result.covs[k]

    def _weigh(self, tracks: list[Track], mask: BoolArray, c: _Checked) -> None:
        """Weigh each particle track by the scan's clutter-aware likelihood."""
        for track, row in zip(tracks, mask, strict=True):
            assert track.cloud is not None  # every track of a "pf" tracker has one
            ell = scan_log_likelihood(
                c.sensor.base,
                c.Z[row],
                track.cloud.X,
                c.s,
                c.scan.fov,
                pd=c.sensor.pd,
                clutter_density=c.sensor.clutter_density,
            )
            track.cloud.weigh(ell)
            track.sync()

    def _resample(self, weighed: set[int]) -> None:
        """Resample (as ``tracker.resample`` says) the clouds weighed this epoch."""
        opts = self.options
        for track in self.book.live():
            if track.cloud is not None and track.track_id in weighed:
                track.cloud.resample_if_due(
                    opts.resample, opts.ess_threshold, opts.roughening, self.rng
                )
                track.sync()

    def _draw_samples(self) -> None:
        """The planner's equally weighted samples of every particle track, by id."""
        for track in self.book.live():
            if track.cloud is not None:
                track.samples = track.cloud.samples(self.options.planner_samples, self.rng)

    # --- track starts ------------------------------------------------------------------------
    def _start(
        self,
        mean: FloatArray,
        cov: FloatArray,
        born: int,
        status: str,
        origin: str,
        priority: float,
    ) -> Track:
        """A new track with the next id (a particle cloud drawn from N(mean, cov) for "pf")."""
        cloud = None
        if self.kind == "pf":
            cloud = ParticleCloud.draw(mean, cov, self.options.particles, self.rng)
        track = Track(self.book.new_id(), status, mean, cov, born, origin, priority, cloud)
        track.sync()
        self.book.add(track)
        return track

    def _start_from_detection(self, z: FloatArray, c: _Checked, epoch: int) -> Track | None:
        """A tentative track at a range-bearing detection ``z = (r, b)`` (inverse measurement
        ``p = s + r (cos b, sin b)``, ``J = dp/dz``), or None past ``max_tracks``."""
        if self.book.full:
            self.book.not_started += 1
            return None
        r, b = float(z[0]), float(z[1])
        cb, sb = math.cos(b), math.sin(b)
        J = np.array([[cb, -r * sb], [sb, r * cb]])
        mean = np.array([c.s[0] + r * cb, 0.0, c.s[2] + r * sb, 0.0])
        cov = np.diag(np.full(4, self.options.tracks.init_speed_std**2))
        cov[_XY] = J @ np.asarray(c.sensor.base.R, dtype=float) @ J.T
        track = self._start(mean, cov, epoch, TENTATIVE, "", self.new_track_priority)
        track.existence = EXISTENCE_INIT
        return track


def _detections(i: int, scan: Scan, sensor: ClutteredSensor) -> FloatArray:
    """The scan's detections as ``(m, dim_z)``, checked (an empty array of any shape: m = 0)."""
    d = int(sensor.base.dim_z)
    Z = np.asarray(scan.Z, dtype=float)
    if Z.size == 0 and Z.ndim in (1, 2):
        return np.zeros((0, d))
    if Z.ndim != 2 or Z.shape[1] != d:
        raise ValueError(f"scans[{i}].Z: must have shape (m, {d}), got {Z.shape}")
    if not np.isfinite(Z).all():
        raise ValueError(f"scans[{i}].Z: must be finite (no NaN or inf)")
    return Z


def _platform(i: int, scan: Scan) -> FloatArray:
    s = np.asarray(scan.sensor_pv, dtype=float)
    if s.shape != (4,) or not np.isfinite(s).all():
        raise ValueError(f"scans[{i}].sensor_pv: must be a finite pv of shape (4,), got {s!r}")
    return s


def _fov_coverage(
    means: FloatArray, covs: FloatArray, fov: FieldOfView, s: FloatArray
) -> FloatArray:
    """Probability ``(T,)`` that each track's target N(mean, cov) lies in the bearing sector
    of ``fov`` seen from ``s`` (:func:`activetrack.planning.assignment.sector_coverage`); 1
    all around. The ranges are not counted."""
    if fov.width >= 2.0 * math.pi:
        return np.ones(means.shape[0])
    off = np.angle(np.exp(1j * (np.arctan2(means[:, 2] - s[2], means[:, 0] - s[0]) - fov.centre)))
    return sector_coverage(fov.width, off, means, covs, s)


def _clusters(mask: BoolArray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Tracks linked through shared gated detections: ``(rows, cols)`` per cluster (tracks
    without a gated detection are in none). The JPDA's joint events factorise over them."""
    label = np.arange(mask.shape[0])
    for j in range(mask.shape[1]):
        rows = np.flatnonzero(mask[:, j])
        if rows.size > 1:
            joined = np.isin(label, label[rows])
            label[joined] = label[rows].min()
    gated = mask.any(axis=1)
    out = []
    for lab in np.unique(label[gated]):
        rows = np.flatnonzero((label == lab) & gated)
        out.append((rows, np.flatnonzero(mask[rows].any(axis=0))))
    return out
