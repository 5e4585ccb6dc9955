"""The tracker: the scenario's filter (any registered one, activetrack.filters.registry) fed
with the simulator's measurements."""

from __future__ import annotations

from typing import cast

import numpy as np

from activetrack.closed_loop.data import TrackSnapshot
from activetrack.filters import filter_kind, make_filter
from activetrack.filters.measurement import Measurement
from activetrack.filters.registry import ParticlePosterior
from activetrack.filters.resampling import systematic_resample
from activetrack.kernels import expect_particle_work
from activetrack.scenarios.build import build_motion_model, build_sensor
from activetrack.scenarios.schema import Scenario


class TrackerCore:
    """Wraps one filter; draws only from its own ``rng`` (particles and planner samples)."""

    def __init__(self, scenario: Scenario, rng: np.random.Generator):
        cfg = scenario.tracker
        motion_cfg = cfg.motion or scenario.target.motion
        self.model = build_motion_model(motion_cfg)
        self.motion_name = motion_cfg.model
        self.kind = cfg.filter
        self.rng = rng
        self.planner_samples = cfg.planner_samples
        # Sensor models by id: messages name a sensor, the scenario says what it is.
        self.sensors = {s.id: build_sensor(s) for p in scenario.platforms for s in p.sensors}
        prior = scenario.target.prior
        # The registered factory reads its own options from the tracker block (the PF its
        # particles, ...) and draws only from this tracker's rng.
        self.particle_based = filter_kind(self.kind).particle_based
        if self.particle_based:  # a long run loads the PF kernels now, not in mid-run
            expect_particle_work(scenario.steps * cfg.particles)
        self.filter = make_filter(
            self.kind, self.model, np.array(prior.mean), prior.covariance(), cfg, rng
        )
        self.epoch = 0
        self.update_count = 0
        self.missed = 0
        self.last_nis = float("nan")
        self.last_ess = float("nan")
        self._samples = self._draw_samples()

    def step(self, epoch: int, t: float, measurements: list[Measurement]) -> TrackSnapshot:
        """Predict to ``t``, update with the epoch's measurements, return the posterior."""
        info = self.filter.step(t, measurements)
        self.epoch = epoch
        self.update_count += 1
        self.missed += info.n_missed
        self.last_nis = info.nis
        self.last_ess = info.ess
        self._samples = self._draw_samples()
        return self.snapshot()

    def _particles(self) -> ParticlePosterior | None:
        """The filter's particle set, for a ``particle_based`` filter (the registry's flag)."""
        return cast(ParticlePosterior, self.filter) if self.particle_based else None

    def _draw_samples(self) -> np.ndarray | None:
        """The planner's equally weighted posterior samples (particle-based filters), drawn
        once per update: a systematic resample thinned to ``planner_samples``."""
        posterior = self._particles()
        if posterior is None:
            return None
        weights = posterior.weights
        count = len(weights)
        idx = systematic_resample(weights, self.rng)
        take = np.linspace(0, count - 1, min(self.planner_samples, count)).astype(int)
        return posterior.particles[idx[take]]

    def snapshot(self) -> TrackSnapshot:
        """The posterior after the last update. Pure: it draws nothing, so looking at the
        track (a notebook, a second caller) never changes a later result."""
        samples = self._samples
        posterior = self._particles()
        count = len(posterior.weights) if posterior is not None else 0
        return TrackSnapshot(
            epoch=self.epoch,
            time=self.filter.time,
            filter_kind=self.kind,
            motion_model=self.motion_name,
            state_names=tuple(self.model.state_names),
            mean=np.array(self.filter.mean),
            cov=np.array(self.filter.cov),
            samples=samples,
            update_count=self.update_count,
            missed_detections=self.missed,
            nis=self.last_nis,
            ess=self.last_ess,
            particle_count=count,
        )


def pose_of(snapshot: TrackSnapshot, model) -> tuple[float, float, float, np.ndarray]:
    """Position x, y, course (rad from +x) and the (x, y) covariance ``(2, 2)`` of a track."""
    pv = model.kinematics(snapshot.mean)
    K = model.kinematics_jacobian(snapshot.mean)
    P = K @ snapshot.cov @ K.T
    return float(pv[0]), float(pv[2]), float(np.arctan2(pv[3], pv[1])), P[np.ix_([0, 2], [0, 2])]
