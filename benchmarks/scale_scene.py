"""Scenes of many spread-out targets for timing the tracker step at scale (issue 28).

``build(n_targets, seed)`` gives a :class:`ScaleScene`: ``n_targets`` NCV targets spread over a
square of ``cells x cells`` radar cells (about ``TARGETS_PER_CELL`` targets per cell, ``cells =
round(sqrt(n / TARGETS_PER_CELL))``: 1 radar for 3 targets, 4 for 30, 16 for 100, 36 for 300,
121 for 1,000), one stationary all-around range-bearing radar at each cell's centre reaching
``REACH`` cell sides (so neighbouring radars overlap a little), Pd 0.9 and about
``CLUTTER_PER_SCAN`` false alarms per scan and radar. Every target has a prior (a track from
epoch 0); clutter starts tentative tracks, so the step runs everything ``batch`` runs: the
prediction, association, initiation, M-of-N, existence, deletion and coalescence.

``scene.tracker()`` is a fresh :class:`activetrack.tracking.tracker.Tracker` with the EKF and
the schema's default ``tracker.tracks`` except ``max_tracks`` (room for every tentative track
clutter starts: never full here); ``scene.scans[k]`` the epoch ``k + 1`` scans. Everything is
drawn from ``default_rng(seed)``. Used by ``benchmarks/step_profile.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from activetrack.data import Scan
from activetrack.filters.ekf import ExtendedKalmanFilter
from activetrack.models.clutter import ClutteredSensor
from activetrack.models.fov import FieldOfView
from activetrack.models.motion import NearlyConstantVelocity
from activetrack.models.sensors import RangeBearingSensor
from activetrack.scenarios.schema import TrackManagementConfig
from activetrack.tracking.tracker import FilterSpec, Tracker, TrackPrior

__all__ = ["ScaleScene", "build"]

TARGETS_PER_CELL = 8
CELL = 10_000.0  # m, side of one radar's cell
REACH = 0.75  # radar r_max in cell sides (the cell's corner is at 0.71)
CLUTTER_PER_SCAN = 20.0  # mean false alarms per scan and radar
DT = 5.0  # s between epochs
Q = 0.01  # NCV process noise PSD, m^2/s^3
SPEED = 10.0  # m/s
PRIOR_STD = (100.0, 3.0, 100.0, 3.0)
SIGMA_R, SIGMA_B, PD = 50.0, 0.02, 0.9
R_MIN = 100.0


@dataclass
class ScaleScene:
    """One seeded scene: ``n_targets``, ``cells`` per side, the radars' ``sensors`` (id ->
    sensor) and ``sites`` (id -> pv ``(4,)``, fov), ``priors`` and ``scans`` per epoch."""

    n_targets: int
    cells: int
    sensors: dict[str, ClutteredSensor]
    sites: dict[str, tuple[np.ndarray, FieldOfView]]
    priors: list[TrackPrior]
    truth: np.ndarray  # (K + 1, n, 4)
    scans: list[list[Scan]]
    max_tracks: int

    def tracker(self, seed: int = 0) -> Tracker:
        """A fresh tracker of the scene (EKF, default track management but ``max_tracks``)."""
        model = NearlyConstantVelocity(Q)
        # model_copy: the older schema capped max_tracks lower (the same scene times both)
        cfg = TrackManagementConfig().model_copy(update={"max_tracks": self.max_tracks})

        def make(x0: np.ndarray, P0: np.ndarray, t0: float) -> ExtendedKalmanFilter:
            return ExtendedKalmanFilter(model, x0, P0, t0)

        return Tracker(
            model,
            "ncv",
            FilterSpec(
                "ekf", False, make, lambda X0, P0, t0: ExtendedKalmanFilter.many(model, X0, P0, t0)
            ),
            self.sensors,
            self.priors,
            known_association=False,
            management=cfg,
            planner_samples=1,
            new_track_priority=1.0,
            rng=np.random.default_rng(seed),
        )


def build(
    n_targets: int, seed: int = 0, steps: int = 10, clutter_per_scan: float = CLUTTER_PER_SCAN
) -> ScaleScene:
    """The scene of ``n_targets`` targets over ``steps`` epochs (module docstring)."""
    if n_targets < 1 or steps < 1:
        raise ValueError(f"n_targets and steps must be >= 1, got {n_targets}, {steps}")
    rng = np.random.default_rng(seed)
    cells = max(1, round(math.sqrt(n_targets / TARGETS_PER_CELL)))
    side = cells * CELL
    r_max = REACH * CELL
    fov = FieldOfView(0.0, 2.0 * math.pi, R_MIN, r_max)
    # clutter per unit of (range, bearing): CLUTTER_PER_SCAN over the annulus's (r, b) volume
    density = clutter_per_scan / ((r_max - R_MIN) * 2.0 * math.pi)
    sensors, sites = {}, {}
    for i in range(cells):
        for j in range(cells):
            sid = f"radar_{i}_{j}"
            base = RangeBearingSensor(SIGMA_R, SIGMA_B, PD, R_MIN, r_max)
            sensors[sid] = ClutteredSensor(base, density, TrackManagementConfig().gate_sigmas)
            pv = np.array([(i + 0.5) * CELL, 0.0, (j + 0.5) * CELL, 0.0])
            sites[sid] = (pv, fov)
    model = NearlyConstantVelocity(Q)
    heading = rng.uniform(-math.pi, math.pi, n_targets)
    x = np.column_stack(
        [
            rng.uniform(0.0, side, n_targets),
            SPEED * np.cos(heading),
            rng.uniform(0.0, side, n_targets),
            SPEED * np.sin(heading),
        ]
    )
    std = np.asarray(PRIOR_STD)
    P0 = np.diag(std**2)
    means = x + rng.standard_normal(x.shape) * std
    priors = [TrackPrior(f"t{k}", means[k], P0) for k in range(n_targets)]
    truth = [x]
    scans: list[list[Scan]] = []
    for k in range(1, steps + 1):
        x = model.sample(x, DT, rng)
        truth.append(x)
        row = []
        for sid, sensor in sensors.items():
            pv, view = sites[sid]
            X = x[view.contains(x, pv)]
            seen = X[sensor.detect(X, pv, rng)]
            Z = np.concatenate([sensor.sample(seen, pv, rng), sensor.sample_clutter(view, rng)])
            row.append(Scan(sid, k, k * DT, pv, Z[rng.permutation(len(Z))], view))
        scans.append(row)
    # room for every tentative track clutter starts (about 3 epochs of each scan's false alarms)
    max_tracks = n_targets + math.ceil(4 * clutter_per_scan) * cells**2 + 100
    return ScaleScene(n_targets, cells, sensors, sites, priors, np.array(truth), scans, max_tracks)
