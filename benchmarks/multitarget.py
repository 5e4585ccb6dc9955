"""Multi-target tracking side by side with Stone Soup on identical detections (issues 14 and 28).

Run with ``.venv/bin/python benchmarks/multitarget.py [--quick] [--runs N] [--jpda-runs N]
[--sizes N ...] [--clutter C ...] [--budget S] [--epochs K] [--managers [--manager-runs N]
[--candidates N] [--jobs J]]`` after ``make bench`` (Stone Soup and pyehm are bench-only
dependencies, ``requirements-bench.txt``). The last line is ::

    tracker_step_speedup_vs_stonesoup=<x> n300_step_ms=<y> n1000_step_ms=<z>
    crowded10_gospa_equals_exact=<true|false>

- x: the full tracker step against Stone Soup's full tracker on the 3-target scene, the median
  over runs of the per-run paired ratio (their total step time / ours in the same run; the two
  take turns run by run in alternating order);
- y, z: our median step (ms) at 300 and 1,000 spread-out targets in the scale table (lowest
  clutter; ``over_budget`` when no epoch finished within the table's budget);
- every figure is of the exact JPDA: our tracker runs with ``oversize_cluster: prune`` and
  the line before the last prints the clusters it pruned behind each (0 each; otherwise it
  says NOT EXACT);
- the crowded flag: on 10 targets crossing at one point (the bare filter's radar and
  clutter), our tracker's time-averaged GOSPA equals that of Stone Soup's exact JPDA (its
  efficient hypothesis management, ``JPDAWithEHM2``) within 0.01 m, association alone: no
  initiation and no track deleted (the exact JPDA deletes none; coalescence held off). The
  GOSPA with our track management as configured is printed beside it with the deletions by
  reason.

``--quick`` (about a minute): part 1 on 2 runs of 20 scans, the bare line on 2 runs, the scale
table on spread scenes of 3, 10, 30, 300 and 1,000 targets at 10 false alarms per scan with a
4 s budget per point, and the crowded check.

Part 1, the full tracker step: :class:`activetrack.tracking.tracker.Tracker` ``step`` (what
``batch`` and the tracker node run: gating, JPDA, existence, initiation, M-of-N, deletion,
coalescence) against Stone Soup's tracker as ``benchmarks/multitarget_tracking.py`` builds it
(``JPDA`` + ``MultiMeasurementInitiator`` + its deleters; reused by import), on the same
detections of 3 crossing targets (that file's ``radar`` scene, priors drawn), each tracker built
and its detections converted before the timing. Each run's time is the sum of its scans' step
times; GOSPA and the tracks each reports are printed beside (Stone Soup's confirms some clutter
tracks).

Part 1, secondary line: the bare association filter (below), ``filters.jpda.jpda_update``
against Stone Soup's bare ``JPDA`` on fixed tracks, also as the median of per-run paired ratios.

The scale table (``benchmarks/multitarget_scale.py``): our step and Stone Soup's JPDA and EHM
(pyehm) from 3 to 1,000 targets, spread and crowded, 10 to 1,000 false alarms per scan and
radar, under a named per-point budget (a point over it says so).

Part 2 (``--managers``, about 30 minutes at 8 runs) compares the sensor managers (below).

The bare association filter: activetrack's JPDA-EKF (``filters.jpda.jpda_update`` after a
batched NCV prediction) against Stone Soup's ``JPDA`` with ``PDAHypothesiser``,
``ExtendedKalmanPredictor`` and ``PDAUpdater`` (its EKF updater with the PDA combined-innovation
update). Both filter the same fixed set of tracks, started from the same priors, with no track
management, so the association filter itself is compared.

Scenario: one stationary range-bearing sensor at (14, 8) km looking west (a 60 degree sector,
ranges 3-12 km: the targets sit at bearings near +-pi, so the bearing wrap is exercised). Three
to five targets (3, 4, 5, 3, ... by run) move with the NCV model (PSD q) and are set up to cross
at (7, 8) km halfway through the run, headings evenly spread over pi. Detections come from
activetrack's own models: each target in the field of view is detected with Pd (drawn from the
run's rng by ``sensor.detect``) and measured by ``sensor.sample``; the false alarms are
``ClutteredSensor.sample_clutter`` (Poisson, uniform over the sector in (range, bearing));
the scan is shuffled, so it carries no labels. Track t starts from N(x0_t + e, P0),
e ~ N(0, P0).

Conventions made equal (checked in tests/core/test_benchmark_multitarget.py):
- state (x, vx, y, vy); Stone Soup's ``ConstantVelocity(q)`` per axis has our
  ``NearlyConstantVelocity(q)`` Q = q [[T^3/3, T^2/2], [T^2/2, T]];
- measurement: ours (range, bearing), Stone Soup's ``CartesianToBearingRange`` (bearing,
  range); the detections are permuted, the clutter density (per m rad) is the same number;
  bearings wrap to [-pi, pi) on both sides (Stone Soup's ``Bearing`` type);
- gate: ours ``nu^T S^-1 nu <= gamma``; Stone Soup's is ``chi2.ppf(prob_gate, 2)``, so it gets
  ``prob_gate = F_chi2(gamma)``, which also enters both filters' ``1 - Pd Pg``;
- Stone Soup's EKF uses a finite-difference Jacobian and ``P - K S K^T``; ours the analytic
  Jacobian and the Joseph form. Its step is ``1e8 * np.spacing(x)``, at least 1e-8; for a
  negative entry ``np.spacing`` is negative, so the step falls to 1e-8 and at |x| = 7 km the
  range row loses about 4e-5 of relative accuracy (tracks then differed by 1-3 cm). The
  scenario therefore keeps every position coordinate positive; the velocities, which h does
  not depend on, give exact zero columns at any step.

Timing: ``time.perf_counter`` around each scan's predict + association + update (our F and Q
are computed once per run, as our EKF caches them); building the detections and reading the
estimates are not timed. One warm-up run each, then the two take turns run by run.

Measured before issue 28 (30 runs, 2-core VM shared with other jobs, load average 2.6; Python
3.11.7, numpy 2.4.6, Stone Soup 1.9.1), as a ratio of total times over all runs, not the paired
median printed now: time-averaged GOSPA 134.6883 m for both; ours - Stone Soup
+7.6e-8 +- 1.0e-7 m, the largest per-run difference 1.5e-6 m and the largest track position
difference at any scan 1.0e-5 m (Stone Soup's finite-difference Jacobian). Update loop: ours
958 us median per scan, Stone Soup 22.5 ms; 33.9x in total time (p10 15.2x, p90 47.5x run by
run; 23.5x on the median scan). Stone Soup's cost grows with the product of the tracks'
gated hypotheses, which it enumerates in full (itertools.product) when the targets cross.

Part 2, the sensor manager: on scenario (b) (``scenarios/mt_radars_beams.yaml``: three radars
with steerable 0.1 rad beams on moving platforms, five targets, clutter), three strategies on
the same seeded runs (``run_once(scenario, run, planner_factory)``; on common random numbers,
run r of every strategy is the same world: target motion, detections, noise and clutter), judged
by the same evaluation (``evaluate_run``, time-averaged GOSPA) and compared by paired
differences run by run with their 95 % intervals (``activetrack.montecarlo.paired``). The
manager is :mod:`activetrack_experiments.stonesoup_manager` (also a strategy of ``activetrack
reproduce multitarget`` on (b) and (d)):

- ``planner``: activetrack's ``MultiTargetPlanner`` as the scenario says (MRE positioning of
  the platforms, MRE beam assignment);
- ``hold_course``: the same with ``planner.enabled: false``: platforms hold course, beams
  still MRE-assigned. Stone Soup steers no platform here, so this is the like-for-like beam
  comparison;
- ``stonesoup``: ``StoneSoupBeamManager``: Stone Soup's ``BruteForceSensorManager`` with its
  ``UncertaintyRewardFunction`` (``KalmanPredictor`` with our F and Q,
  ``ExtendedKalmanUpdater``; reward: the sum over tracks of the drop in the covariance's
  Frobenius norm, sensors updating in turn) chooses the beams' dwell centres; the platforms
  hold course.

Each epoch our confirmed tracks (tentative ones are not planned for, as in our planner) become
Stone Soup ``GaussianState`` tracks; each beam a ``RadarRotatingBearingRange`` (s2, s3; noise
diag(sigma_b^2, sigma_r^2), ``max_range`` r_max) or ``RadarRotatingBearing`` (s1) at its
platform's hold-course position at k+1, ``fov_angle`` the beam width, one turn per epoch (rpm =
60 / dt) so that every bearing is reachable, as our beams are. Action set: Stone Soup's
``DwellActionsGenerator`` offers a uniform grid of dwell centres around the current one; with
0.1 rad beams a grid that covers every track is 63 pointings per beam, 63^3 configurations, and
a coarser one misses tracks between its points. So the radars here offer instead a pointing at
each confirmed track's prediction F x (``listed_radars``: Stone Soup's own ``ChangeDwellAction``
at listed bearings), one per distinct set of covered tracks (``beam_pointings``). Scenario
(b)'s tracker kept 20-45 confirmed tracks before the one closed loop (most from clutter), and
Stone Soup's reward costs ~5-20 ms per configuration, so a beam offering more than
``--candidates`` (default 3) pointings keeps the
3 whose reward alone is largest; the brute force then scores the <= 27 joint configurations.
Only the tracks some offered pointing covers are passed to ``choose_actions`` (the others add
zero to every configuration). Pruning checked: 4 instead of 3 (64 configurations) gave the
same mean GOSPA within noise on 4 runs (1600 vs 1583 m) at about twice the cost; at 10 sampled
epochs of run 1 the joint reward chosen with 3 equalled that with 6 at 8 and was 17 and 19 %
lower at 2. A beam with no pointing in range, or every beam while there is no confirmed track,
sweeps as our planner does (one beam width on per epoch). ``--quick``: part 2 with 2 runs.

Measured before common random numbers, as ratios (8 paired runs, seed 20100622 runs 0-7, 60
epochs; Python 3.11.7, numpy 2.4.6, Stone Soup 1.9.1, a 2-core VM shared with other jobs, load
average 13-15, ``--jobs 1``): time-averaged GOSPA, c = 500 m, p = 2:

    planner        119.5 +- 36.1 m  (missed targets 0.10, false tracks 0.08 per epoch)
    hold_course    102.1 +- 39.7 m  (0.10, 0.04)
    stonesoup      138.4 +- 27.9 m  (0.10, 0.08)

GOSPA(planner) / GOSPA(stonesoup) = 0.863 +- 0.332 and GOSPA(hold_course) / GOSPA(stonesoup) =
0.737 +- 0.368 (paired, delta method): ours lower, within about one SE on 8 runs. Decision time
per epoch: planner 0.58 s, hold_course 0.14 s, Stone Soup 2.2 s (its reward deep-copies the
sensors and runs its EKF per configuration); 27 min of wall time here for part 2.

On common random numbers (``activetrack reproduce multitarget --runs 20 --jobs 1 --scenario
mt_radars_beams``, runs 0-19, the manager's runs by the same code run by run; load average
6-7): planner 119.3 +- 26.3 m, hold_course 77.4 +- 13.1 m, stonesoup 115.7 +- 19.8 m (missed
targets 0.105 / 0.032 / 0.123, false tracks 0.079 / 0.023 / 0.041 per epoch); paired
GOSPA(planner) - GOSPA(stonesoup) +3.6 m [-66.0, +73.1], GOSPA(hold_course) - GOSPA(stonesoup)
-38.4 m [-91.5, +14.8]: neither resolved at 20 runs. Decision time per epoch 0.37 s, 0.10 s and
1.41 s; 30 min of wall time for the manager's 20 runs.

Before the one closed loop (one simulator and tracker for every scene: other random draws, the
registered filters on every track), the same command measured 1818.0 +- 54.3, 1785.0 +- 59.3
and 1583.1 +- 45.1 m, GOSPA then dominated by 20-26 confirmed clutter tracks per epoch (each
costs c^2 / 2); the merged tracker confirms almost none on this scenario.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import importlib.util
import math
import os
import platform
import sys
import time
from collections import Counter
from dataclasses import dataclass, field, replace
from datetime import timedelta
from pathlib import Path
from unittest import mock

import numpy as np

from activetrack import limits
from activetrack.allocator import tune_allocator
from activetrack.argtypes import int_in_range
from activetrack.closed_loop.components import component_rngs
from activetrack.closed_loop.evaluation import evaluate_run
from activetrack.closed_loop.loop import run_once
from activetrack.data import Scan
from activetrack.filters.ekf import ExtendedKalmanFilter
from activetrack.filters.jpda import gate_probability, jpda_update
from activetrack.metrics import gospa
from activetrack.models import NearlyConstantVelocity, RangeBearingSensor
from activetrack.models.clutter import ClutteredSensor
from activetrack.montecarlo import parallel_map
from activetrack.montecarlo.paired import PairedDifference, paired_difference
from activetrack.scenarios import load_scenario
from activetrack.scenarios.schema import Scenario, TrackManagementConfig
from activetrack.tracking import management as track_management
from activetrack.tracking.tracker import FilterSpec, Tracker, TrackPrior
from activetrack_experiments.multitarget import strategy_scenario
from activetrack_experiments.stonesoup_manager import (
    DEFAULT_CANDIDATES,
    EPOCH,
    StoneSoupBeamManager,
)


@dataclass(frozen=True)
class JPDAScenario:
    """Part 1's scenario (module docstring); lengths in m, angles in rad, times in s."""

    T: float = 5.0  # s between scans
    n_steps: int = 40  # scans per run (200 s)
    q: float = 0.01  # NCV process-noise PSD, m^2/s^3
    sigma_r: float = 50.0  # range noise, m
    sigma_b: float = 0.02  # bearing noise, rad (140 m across at 7 km)
    pd: float = 0.9
    clutter_density: float = 2e-3  # false alarms per m rad (lambda V = 18.8 per scan)
    gate_sigmas: float = 4.0  # chi-square gate gamma = 16
    fov_centre: float = math.pi  # sector off the (zero-velocity) heading, i.e. due west
    fov_width: float = math.pi / 3
    r_min: float = 3000.0
    r_max: float = 12000.0
    # All coordinates positive: Stone Soup's finite-difference Jacobian steps a negative state
    # entry by only 1e-8 (module docstring), which would cost it ~1e-4 relative accuracy.
    sensor_xy: tuple[float, float] = (14000.0, 8000.0)
    crossing: tuple[float, float] = (7000.0, 8000.0)
    speed: float = 10.0  # m/s
    prior_std: tuple[float, float, float, float] = (100.0, 3.0, 100.0, 3.0)
    cutoff: float = 500.0  # GOSPA c, m (p = 2, alpha = 2)
    order: float = 2.0

    @property
    def gamma(self) -> float:
        return self.gate_sigmas**2


@dataclass
class Run:
    """One seeded run: truth ``(K + 1, n, 4)`` at scans 0..K, priors ``(n, 4)`` and
    ``(4, 4)``, the unlabelled scans 1..K ``(m_k, 2)`` as (range, bearing)."""

    seed: int
    truth: np.ndarray
    prior_means: np.ndarray
    prior_cov: np.ndarray
    scans: list[np.ndarray]
    sensor_pv: np.ndarray


def make_sensor(sc: JPDAScenario) -> ClutteredSensor:
    base = RangeBearingSensor(sc.sigma_r, sc.sigma_b, sc.pd, sc.r_min, sc.r_max)
    return ClutteredSensor(
        base, sc.clutter_density, sc.gate_sigmas, sc.fov_centre, sc.fov_width, None
    )


def initial_states(sc: JPDAScenario, n: int) -> np.ndarray:
    """pv ``(n, 4)`` of ``n`` targets that would meet at ``sc.crossing`` halfway through the
    run at constant velocity; headings pi (i + 1/2) / n, so no two are parallel."""
    heading = math.pi * (np.arange(n) + 0.5) / n
    v = sc.speed * np.column_stack([np.cos(heading), np.sin(heading)])
    t_cross = 0.5 * sc.n_steps * sc.T
    x0 = np.asarray(sc.crossing) - t_cross * v
    return np.column_stack([x0[:, 0], v[:, 0], x0[:, 1], v[:, 1]])


def simulate(sc: JPDAScenario, seed: int, n_targets: int) -> Run:
    """Truth, priors and scans of one run, all from ``default_rng(seed)``."""
    rng = np.random.default_rng(seed)
    model, sensor = NearlyConstantVelocity(sc.q), make_sensor(sc)
    s = np.array([sc.sensor_xy[0], 0.0, sc.sensor_xy[1], 0.0])
    fov = sensor.field_of_view(s)
    x = initial_states(sc, n_targets)
    truth = [x]
    for _ in range(sc.n_steps):
        x = model.sample(x, sc.T, rng)
        truth.append(x)
    P0 = np.diag(np.square(sc.prior_std))
    prior_means = truth[0] + rng.standard_normal(truth[0].shape) * np.asarray(sc.prior_std)
    scans = []
    for k in range(1, sc.n_steps + 1):
        X = truth[k][fov.contains(truth[k], s)]
        seen = X[sensor.detect(X, s, rng)]
        Z = np.concatenate([sensor.sample(seen, s, rng), sensor.sample_clutter(fov, rng)])
        scans.append(Z[rng.permutation(len(Z))])
    return Run(seed, np.array(truth), prior_means, P0, scans, s)


# --- the two filters: each returns (means (K, n, 4), per-scan times (K,)) --------------------


def run_ours(sc: JPDAScenario, run: Run) -> tuple[np.ndarray, np.ndarray]:
    """activetrack JPDA-EKF: batched NCV prediction, then ``jpda_update`` per scan."""
    model, sensor = NearlyConstantVelocity(sc.q), make_sensor(sc)
    F, Q = model.transition_matrix(sc.T), model.process_noise(sc.T)
    n = run.prior_means.shape[0]
    X = run.prior_means.copy()
    P = np.broadcast_to(run.prior_cov, (n, 4, 4)).copy()
    est, dt = np.empty((sc.n_steps, n, 4)), np.empty(sc.n_steps)
    clock = time.perf_counter
    for k in range(sc.n_steps):
        t0 = clock()
        X = X @ F.T
        P = F @ P @ F.T + Q
        res = jpda_update(
            X, P, run.scans[k], sensor, run.sensor_pv, model,
            clutter_density=sc.clutter_density, gamma=sc.gamma, pd=sc.pd,
        )  # fmt: skip
        X, P = res.means, res.covs
        dt[k] = clock() - t0
        est[k] = X
    return est, dt


def _stonesoup_measurement_model(sc: JPDAScenario, sensor_pv: np.ndarray):
    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
    from stonesoup.types.array import StateVector

    return CartesianToBearingRange(
        ndim_state=4,
        mapping=(0, 2),
        noise_covar=np.diag([sc.sigma_b**2, sc.sigma_r**2]),
        translation_offset=StateVector([sensor_pv[0], sensor_pv[2]]),
    )


def stonesoup_detections(sc: JPDAScenario, run: Run, measurement_model) -> list[set]:
    """Each scan as a set of Stone Soup ``Detection`` (bearing, range), bearing typed."""
    from stonesoup.types.angle import Bearing
    from stonesoup.types.array import StateVector
    from stonesoup.types.detection import Detection

    out = []
    for k, Z in enumerate(run.scans):
        when = EPOCH + timedelta(seconds=sc.T * (k + 1))
        out.append(
            {
                Detection(StateVector([Bearing(b), r]), timestamp=when,
                          measurement_model=measurement_model)
                for r, b in Z
            }
        )  # fmt: skip
    return out


def _stonesoup_jpda(sc: JPDAScenario, measurement_model):
    """Stone Soup's JPDA, PDA hypothesiser and PDA (EKF) updater for ``sc``."""
    from stonesoup.dataassociator.probability import JPDA
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
    )
    from stonesoup.predictor.kalman import ExtendedKalmanPredictor
    from stonesoup.updater.probability import PDAUpdater

    transition = CombinedLinearGaussianTransitionModel(
        [ConstantVelocity(sc.q), ConstantVelocity(sc.q)]
    )
    predictor = ExtendedKalmanPredictor(transition)
    updater = PDAUpdater(measurement_model, force_symmetric_covariance=True)
    hypothesiser = PDAHypothesiser(
        predictor=predictor,
        updater=updater,
        clutter_spatial_density=sc.clutter_density,
        prob_detect=sc.pd,
        prob_gate=gate_probability(sc.gamma, 2),
    )
    return JPDA(hypothesiser=hypothesiser), updater


def run_stonesoup(sc: JPDAScenario, run: Run) -> tuple[np.ndarray, np.ndarray]:
    """Stone Soup JPDA with its EKF on the same scans and priors."""
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track

    mm = _stonesoup_measurement_model(sc, run.sensor_pv)
    associator, updater = _stonesoup_jpda(sc, mm)
    dets = stonesoup_detections(sc, run, mm)
    tracks = [
        Track([GaussianState(m.reshape(4, 1), run.prior_cov, timestamp=EPOCH)])
        for m in run.prior_means
    ]
    n = len(tracks)
    est, dt = np.empty((sc.n_steps, n, 4)), np.empty(sc.n_steps)
    clock = time.perf_counter
    for k in range(sc.n_steps):
        when = EPOCH + timedelta(seconds=sc.T * (k + 1))
        t0 = clock()
        hypotheses = associator.associate(tracks, dets[k], when)
        for track in tracks:
            track.append(updater.update(hypotheses[track]))
        dt[k] = clock() - t0
        est[k] = [np.asarray(t.state_vector, dtype=float)[:, 0] for t in tracks]
    return est, dt


# --- figures ---------------------------------------------------------------------------------


def mean_gospa(sc: JPDAScenario, run: Run, est: np.ndarray) -> float:
    """Time-averaged GOSPA (c = ``sc.cutoff``, p = ``sc.order``, alpha = 2) of the track
    positions against the truth positions over scans 1..K."""
    pos = [0, 2]
    d = [
        gospa(run.truth[k + 1][:, pos], est[k][:, pos], sc.cutoff, sc.order).distance
        for k in range(sc.n_steps)
    ]
    return float(np.mean(d))


@dataclass
class JPDAComparison:
    """Part 1's figures over ``len(seeds)`` runs: per-run time-averaged GOSPA of each filter
    (m), the largest position difference between the two filters' tracks at any scan (m),
    and the per-scan wall times (s) of each, ``(runs, K)``."""

    seeds: list[int]
    n_targets: list[int]
    gospa_ours: np.ndarray
    gospa_theirs: np.ndarray
    max_state_diff: np.ndarray
    times_ours: np.ndarray
    times_theirs: np.ndarray

    @property
    def gospa_diff(self) -> tuple[float, float]:
        """Mean of ours - theirs over runs and its Monte Carlo standard error."""
        d = self.gospa_ours - self.gospa_theirs
        se = float(d.std(ddof=1) / math.sqrt(d.size)) if d.size > 1 else math.nan
        return float(d.mean()), se

    @property
    def speedup(self) -> float:
        """Their total update-loop time over ours (same scans)."""
        return float(self.times_theirs.sum() / self.times_ours.sum())

    def speedup_spread(self) -> tuple[float, float]:
        """10th and 90th percentiles over the runs of the per-run time ratio."""
        r = self.times_theirs.sum(axis=1) / self.times_ours.sum(axis=1)
        lo, hi = np.percentile(r, [10, 90])
        return float(lo), float(hi)

    @property
    def paired_speedup(self) -> float:
        """The median over the runs of the per-run time ratio (theirs / ours, same run)."""
        return float(np.median(self.times_theirs.sum(axis=1) / self.times_ours.sum(axis=1)))


def compare_jpda(sc: JPDAScenario, seeds: list[int], warm_up: bool = True) -> JPDAComparison:
    """Part 1: both JPDA filters on the same runs (3, 4, 5, 3, ... targets), taking turns."""
    runs = [simulate(sc, s, 3 + i % 3) for i, s in enumerate(seeds)]
    impls = [run_ours, run_stonesoup]
    if warm_up:
        for fn in impls:
            fn(sc, runs[0])
    out: dict = {fn: ([], []) for fn in impls}
    for i, run in enumerate(runs):
        for fn in impls if i % 2 == 0 else impls[::-1]:
            est, dt = fn(sc, run)
            out[fn][0].append(est)
            out[fn][1].append(dt)
    (ours, t_ours), (theirs, t_theirs) = out[run_ours], out[run_stonesoup]
    diff = [np.max(np.abs(a - b)[..., [0, 2]]) for a, b in zip(ours, theirs, strict=True)]
    return JPDAComparison(
        seeds=list(seeds),
        n_targets=[r.prior_means.shape[0] for r in runs],
        gospa_ours=np.array([mean_gospa(sc, r, e) for r, e in zip(runs, ours, strict=True)]),
        gospa_theirs=np.array([mean_gospa(sc, r, e) for r, e in zip(runs, theirs, strict=True)]),
        max_state_diff=np.array(diff),
        times_ours=np.array(t_ours),
        times_theirs=np.array(t_theirs),
    )


def print_jpda(sc: JPDAScenario, c: JPDAComparison) -> None:
    print(
        f"# JPDA-EKF on identical detections, {len(c.seeds)} runs "
        f"(seeds {c.seeds[0]}..{c.seeds[-1]}, targets {sorted(set(c.n_targets))}), "
        f"{sc.n_steps} scans of T={sc.T} s, Pd={sc.pd}, clutter {sc.clutter_density} /(m rad), "
        f"gate gamma={sc.gamma:g}, GOSPA c={sc.cutoff:g} m p={sc.order:g} alpha=2"
    )
    print(f"{'run':>4} {'seed':>6} {'n':>2} {'GOSPA ours':>11} {'Stone Soup':>11} "
          f"{'ours - SS':>10} {'max |dx|':>9}")  # fmt: skip
    for i, s in enumerate(c.seeds):
        a, b = c.gospa_ours[i], c.gospa_theirs[i]
        print(f"{i:4d} {s:6d} {c.n_targets[i]:2d} {a:11.4f} {b:11.4f} {a - b:+10.2e} "
              f"{c.max_state_diff[i]:9.2e}")  # fmt: skip
    d, se = c.gospa_diff
    print(
        f"time-averaged GOSPA: ours {c.gospa_ours.mean():.4f} m, Stone Soup "
        f"{c.gospa_theirs.mean():.4f} m; ours - Stone Soup {d:+.3e} +- {se:.1e} m (MC SE), "
        f"largest per-run |difference| {np.abs(c.gospa_ours - c.gospa_theirs).max():.2e} m, "
        f"largest track position difference {c.max_state_diff.max():.2e} m"
    )
    to, tt = c.times_ours, c.times_theirs
    lo, hi = c.speedup_spread()
    print(
        f"update loop wall time (predict + associate + update): ours {to.sum():.3f} s "
        f"({np.median(to) * 1e6:.0f} us median per scan), Stone Soup {tt.sum():.3f} s "
        f"({np.median(tt) * 1e6:.0f} us)"
    )
    print(
        f"bare jpda_update vs Stone Soup's bare JPDA: paired ratio (theirs / ours, run by run) "
        f"median {c.paired_speedup:.1f}x [p10 {lo:.1f}, p90 {hi:.1f}]; total times "
        f"{c.speedup:.1f}x; median scans {np.median(tt) / np.median(to):.1f}x"
    )


# --- part 1: the full tracker step against Stone Soup's full tracker ------------------------

TRACKER_TARGETS = 3  # targets of part 1's tracker scene (the issue's 3-target scene)
TRACKER_SCENE = "radar"  # benchmarks/multitarget_tracking.py's one radar


def _sibling(stem: str):
    """``benchmarks/<stem>.py`` loaded once, as module ``bench_<stem>``."""
    name = f"bench_{stem}"
    if name not in sys.modules:
        path = Path(__file__).resolve().parent / f"{stem}.py"
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses look their module up
        spec.loader.exec_module(module)
    return sys.modules[name]


def tracking_module():
    """``benchmarks/multitarget_tracking.py`` (its scene and both full trackers), loaded once."""
    return _sibling("multitarget_tracking")


def timed_run(stepper, n_scans: int) -> tuple[list[np.ndarray], np.ndarray]:
    """A tracker's reported positions at scans 1..``n_scans`` and the wall time of each scan's
    ``step`` (s); reading the positions is not timed."""
    out, dt = [], np.empty(n_scans)
    clock = time.perf_counter
    for k in range(1, n_scans + 1):
        t0 = clock()
        stepper.step(k)
        dt[k - 1] = clock() - t0
        out.append(stepper.positions())
    return out, dt


@dataclass
class TrackerComparison:
    """The full trackers on the same worlds: per-run time-averaged GOSPA (m), mean tracks
    reported per scan and per-scan wall times (s) ``(runs, K)`` of each."""

    seeds: list[int]
    gospa_ours: np.ndarray
    gospa_theirs: np.ndarray
    tracks_ours: np.ndarray
    tracks_theirs: np.ndarray
    times_ours: np.ndarray
    times_theirs: np.ndarray
    pruned: int = 0  # JPDA clusters ours pruned over all runs (0: every one exact)

    @property
    def ratios(self) -> np.ndarray:
        """Per run: their total step time / ours (the same run, the two taking turns)."""
        return self.times_theirs.sum(axis=1) / self.times_ours.sum(axis=1)

    @property
    def paired_speedup(self) -> float:
        """The headline: the median over the runs of :attr:`ratios`."""
        return float(np.median(self.ratios))

    def spread(self) -> tuple[float, float]:
        """10th and 90th percentiles of :attr:`ratios`."""
        lo, hi = np.percentile(self.ratios, [10, 90])
        return float(lo), float(hi)


def compare_trackers(
    seeds: list[int], n_scans: int | None = None, warm_up: bool = True
) -> TrackerComparison:
    """Part 1: our ``Tracker.step`` and Stone Soup's tracker (JPDA, initiator, deleters) on the
    same detections of :data:`TRACKER_TARGETS` crossing targets, scans 1..``n_scans`` (all),
    taking turns run by run in alternating order; each tracker is built, and its detections
    converted, before the timing starts."""
    mtt = tracking_module()
    worlds = [mtt.simulate(TRACKER_SCENE, "drawn", s, TRACKER_TARGETS) for s in seeds]
    K = len(worlds[0].scans) if n_scans is None else n_scans
    makers = [mtt.ours, mtt.stonesoup]
    if warm_up:
        for make in makers:
            timed_run(make(TRACKER_SCENE, worlds[0]), min(K, 5))
    got: dict = {make: [] for make in makers}
    pruned = 0
    for i, world in enumerate(worlds):
        for make in makers if i % 2 == 0 else makers[::-1]:
            stepper = make(TRACKER_SCENE, world)
            got[make].append(timed_run(stepper, K))
            pruned += stepper.pruned()

    def figures(make):
        runs = got[make]
        g = [
            mtt.mean_gospa(replace_scans(w, K), pos)
            for w, (pos, _) in zip(worlds, runs, strict=True)
        ]
        n = [np.mean([len(p) for p in pos]) for pos, _ in runs]
        return np.array(g), np.array(n), np.array([dt for _, dt in runs])

    (g_o, n_o, t_o), (g_t, n_t, t_t) = figures(mtt.ours), figures(mtt.stonesoup)
    return TrackerComparison(list(seeds), g_o, g_t, n_o, n_t, t_o, t_t, pruned)


def replace_scans(world, n_scans: int):
    """``world`` cut to its first ``n_scans`` scans (its GOSPA over those)."""
    return replace(world, scans=world.scans[:n_scans])


def print_trackers(c: TrackerComparison, n_scans: int) -> None:
    print(
        f"# part 1: the full tracker step (Tracker.step: association, track management, "
        f"initiation, what `batch` runs) against Stone Soup's tracker (JPDA + "
        f"MultiMeasurementInitiator + deleters, benchmarks/multitarget_tracking.py), "
        f"{len(c.seeds)} runs (seeds {c.seeds[0]}..{c.seeds[-1]}), {TRACKER_TARGETS} crossing "
        f"targets, one radar, {n_scans} scans, same detections, alternating order"
    )
    print(f"{'run':>4} {'seed':>6} {'ours ms/scan':>12} {'SS ms/scan':>11} {'ratio':>7} "
          f"{'GOSPA ours':>11} {'SS':>8} {'tracks ours':>11} {'SS':>6}")  # fmt: skip
    for i, s in enumerate(c.seeds):
        print(
            f"{i:4d} {s:6d} {c.times_ours[i].mean() * 1e3:12.2f} "
            f"{c.times_theirs[i].mean() * 1e3:11.2f} {c.ratios[i]:6.1f}x "
            f"{c.gospa_ours[i]:11.1f} {c.gospa_theirs[i]:8.1f} {c.tracks_ours[i]:11.1f} "
            f"{c.tracks_theirs[i]:6.1f}"
        )
    lo, hi = c.spread()
    print(
        f"tracker step: ours {np.median(c.times_ours) * 1e3:.2f} ms median per scan, Stone Soup "
        f"{np.median(c.times_theirs) * 1e3:.2f} ms; paired ratio (theirs / ours, run by run) "
        f"median {c.paired_speedup:.1f}x [p10 {lo:.1f}, p90 {hi:.1f}]  (target >= 15x: "
        f"{'met' if c.paired_speedup >= 15 else 'MISSED'})"
    )
    sc = JPDAScenario()
    print(
        f"time-averaged GOSPA (c={sc.cutoff:g} m, p={sc.order:g}): ours "
        f"{c.gospa_ours.mean():.1f} m, Stone Soup {c.gospa_theirs.mean():.1f} m; tracks "
        f"reported per scan: ours {c.tracks_ours.mean():.1f}, Stone Soup "
        f"{c.tracks_theirs.mean():.1f} ({TRACKER_TARGETS} targets)"
    )


# --- crowded: our tracker's association against Stone Soup's exact JPDA ----------------------

CROWDED_TARGETS = 10  # all crossing at one point halfway (the issue's crowded 10-target scene)
CROWDED_SEEDS = (2000,)
CROWDED_TOLERANCE_M = 0.01  # time-averaged GOSPA agreement that counts as equal


def _positions_gospa(sc: JPDAScenario, run: Run, positions: list[np.ndarray]) -> float:
    """Time-averaged GOSPA of reported positions ``(n_k, 2)`` at scans 1..K."""
    d = [
        gospa(run.truth[k + 1][:, [0, 2]], Y, sc.cutoff, sc.order).distance
        for k, Y in enumerate(positions)
    ]
    return float(np.mean(d))


def crowded_ours(
    sc: JPDAScenario, run: Run, management: bool = False
) -> tuple[list[np.ndarray], Counter[str]]:
    """Our tracker on the bare-filter scene's scans, no initiation (tracks from the priors
    only), gate ``sc.gate_sigmas``: its confirmed tracks' positions per scan and its counters
    (deletions by reason). ``management=False`` isolates the association: no track is deleted
    (no miss count, existence or position-std limit, and coalescence held off by
    ``COALESCE_LOOKS`` beyond the run), as the exact JPDA it is compared with deletes none."""
    if management:
        cfg = TrackManagementConfig(
            gate_sigmas=sc.gate_sigmas, initiate=False, oversize_cluster="prune"
        )
        hold = contextlib.nullcontext()
    else:
        cfg = TrackManagementConfig(
            gate_sigmas=sc.gate_sigmas, initiate=False, delete_misses=1000,
            max_position_std=limits.MAX_RANGE, existence_terminate=0.0,
            existence_terminate_prior=0.0, oversize_cluster="prune",
        )  # fmt: skip
        hold = mock.patch.object(track_management, "COALESCE_LOOKS", sc.n_steps + 1)
    model, sensor = NearlyConstantVelocity(sc.q), make_sensor(sc)

    def make(x0: np.ndarray, P0: np.ndarray, t0: float) -> ExtendedKalmanFilter:
        return ExtendedKalmanFilter(model, x0, P0, t0)

    tracker = Tracker(
        model, "ncv", FilterSpec("ekf", False, make), {"radar": sensor},
        [TrackPrior(f"t{i}", m, run.prior_cov) for i, m in enumerate(run.prior_means)],
        known_association=False, management=cfg, planner_samples=1, new_track_priority=1.0,
        rng=np.random.default_rng(run.seed),
    )  # fmt: skip
    fov = sensor.field_of_view(run.sensor_pv)
    out = []
    with hold:
        for k, Z in enumerate(run.scans, start=1):
            ts = tracker.step(k, k * sc.T, [Scan("radar", k, k * sc.T, run.sensor_pv, Z, fov)])
            out.append(np.array([tr.mean[[0, 2]] for tr in ts.confirmed]).reshape(-1, 2))
    return out, tracker.counters


def crowded_exact(sc: JPDAScenario, run: Run) -> list[np.ndarray]:
    """Stone Soup's exact JPDA (efficient hypothesis management, ``JPDAWithEHM2`` of its pyehm
    plugin; the same marginals as ``JPDA``'s full enumeration) with its EKF: positions per
    scan."""
    from stonesoup.plugins.pyehm import JPDAWithEHM2
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track

    mm = _stonesoup_measurement_model(sc, run.sensor_pv)
    associator, updater = _stonesoup_jpda(sc, mm)
    associator = JPDAWithEHM2(hypothesiser=associator.hypothesiser)
    dets = stonesoup_detections(sc, run, mm)
    tracks = [
        Track([GaussianState(m.reshape(4, 1), run.prior_cov, timestamp=EPOCH)])
        for m in run.prior_means
    ]
    out = []
    for k in range(sc.n_steps):
        hypotheses = associator.associate(
            tracks, dets[k], EPOCH + timedelta(seconds=sc.T * (k + 1))
        )
        for track in tracks:
            track.append(updater.update(hypotheses[track]))
        out.append(np.array([np.asarray(t.state_vector, dtype=float)[[0, 2], 0] for t in tracks]))
    return out


@dataclass
class CrowdedCheck:
    """Per seed: time-averaged GOSPA (m) of our tracker's association (no track deleted), of
    Stone Soup's exact JPDA, and of our tracker with its track management as configured, with
    that run's deletions by reason."""

    seeds: list[int]
    ours: np.ndarray
    exact: np.ndarray
    managed: np.ndarray
    deletions: list[dict[str, int]]
    pruned: int = 0  # JPDA clusters ours pruned, both runs of every seed (0: all exact)

    @property
    def equal(self) -> bool:
        return bool(np.all(np.abs(self.ours - self.exact) <= CROWDED_TOLERANCE_M))


def check_crowded(sc: JPDAScenario, seeds=CROWDED_SEEDS, n: int = CROWDED_TARGETS) -> CrowdedCheck:
    """Our tracker against Stone Soup's exact JPDA on ``n`` targets crossing at one point."""
    runs = [simulate(sc, s, n) for s in seeds]
    ours, managed, deletions, pruned = [], [], [], 0
    for r in runs:
        positions, counters = crowded_ours(sc, r)
        ours.append(_positions_gospa(sc, r, positions))
        pruned += counters["association.pruned_clusters"]
        positions, counters = crowded_ours(sc, r, management=True)
        managed.append(_positions_gospa(sc, r, positions))
        deletions.append({k: v for k, v in counters.items() if k.startswith("deleted") and v})
        pruned += counters["association.pruned_clusters"]
    exact = [_positions_gospa(sc, r, crowded_exact(sc, r)) for r in runs]
    return CrowdedCheck(
        list(seeds), np.array(ours), np.array(exact), np.array(managed), deletions, pruned
    )


def print_crowded(c: CrowdedCheck, n: int = CROWDED_TARGETS) -> None:
    print(
        f"# crowded: {n} targets crossing at one point, the bare filter's radar and clutter, no "
        f"initiation: our tracker's association (no track deleted) against Stone Soup's exact "
        f"JPDA (EHM), time-averaged GOSPA"
    )
    for i, s in enumerate(c.seeds):
        a, b = c.ours[i], c.exact[i]
        same = abs(a - b) <= CROWDED_TOLERANCE_M
        print(
            f"seed {s}: ours {a:.4f} m, exact {b:.4f} m, difference {a - b:+.2e} m (equal "
            f"within {CROWDED_TOLERANCE_M} m: {same}); with our track management as configured "
            f"{c.managed[i]:.4f} m, deletions {c.deletions[i] or 'none'}"
        )


# --- part 2: the sensor manager on scenario (b) ----------------------------------------------

SCENARIO_B = Path(__file__).resolve().parents[1] / "scenarios" / "mt_radars_beams.yaml"
# Part 2's strategies, as printed: our planner (manoeuvres + MRE beams), our MRE beams with the
# platforms holding course, Stone Soup's manager pointing the beams (platforms holding course).
MANAGERS = ("planner", "hold_course", "stonesoup")
DEFAULT_MANAGER_RUNS = 8  # paired runs of part 2 (module docstring)


@dataclass(frozen=True)
class ManagerRun:
    """One run of a strategy: time-averaged GOSPA [m], mean missed targets and false tracks
    per epoch (its alpha = 2 split), decision wall time [s] and decisions."""

    gospa: float
    missed: float
    false: float
    decide_s: float
    epochs: int


def run_manager(task: tuple[Scenario, int, str, int]) -> ManagerRun:
    """One closed-loop run ``(scenario, run, strategy, candidates)`` of a :data:`MANAGERS`
    strategy, evaluated by :func:`evaluate_run`."""
    scenario, run, strategy, candidates = task
    if strategy not in MANAGERS:
        raise ValueError(f"strategy must be one of {MANAGERS}, got {strategy!r}")
    factory = None
    if strategy != "planner":
        scenario = strategy_scenario(scenario, "hold_course")
    if strategy == "stonesoup":
        factory = functools.partial(StoneSoupBeamManager, candidates=candidates)
    record = run_once(scenario, run, factory)
    # The bound's samples do not enter GOSPA: a few keep the evaluation cheap.
    ev = evaluate_run(scenario, record, component_rngs(scenario.seed, run)[3], n_samples=8)
    return ManagerRun(
        ev.mean_gospa,
        float(ev.missed.mean()),
        float(ev.false.mean()),
        record.planning_time_s,
        len(record.decisions),
    )


@dataclass
class ManagerComparison:
    """Part 2's figures: per strategy (:data:`MANAGERS`) each run's time-averaged GOSPA ``(R,)``
    [m], the mean missed targets and false tracks per epoch, and the mean decision wall time
    per epoch [s]; the runs are paired (same seeds)."""

    runs: list[int]
    gospa: dict[str, np.ndarray]
    decide_s: dict[str, float]
    candidates: int = DEFAULT_CANDIDATES
    missed: dict[str, float] = field(default_factory=dict)
    false: dict[str, float] = field(default_factory=dict)

    def mean_se(self, strategy: str) -> tuple[float, float]:
        g = self.gospa[strategy]
        se = float(g.std(ddof=1) / math.sqrt(g.size)) if g.size > 1 else math.nan
        return float(g.mean()), se

    def paired(self, a: str, b: str) -> PairedDifference:
        """GOSPA(a) - GOSPA(b) run by run (the runs share their worlds: common random numbers)
        with its 95 % Student-t interval (negative: ``a`` lower)."""
        return paired_difference(self.gospa[a], self.gospa[b])


def compare_managers(
    scenario: Scenario, runs: list[int], candidates: int = DEFAULT_CANDIDATES, jobs: int = 2
) -> ManagerComparison:
    """Part 2: every strategy on the same seeded runs of ``scenario``, on ``jobs`` processes."""
    tasks = [(scenario, r, s, candidates) for r in runs for s in MANAGERS]
    results = parallel_map(run_manager, tasks, jobs)
    by = {s: [res for (_, _, name, _), res in zip(tasks, results, strict=True) if name == s]
          for s in MANAGERS}  # fmt: skip
    return ManagerComparison(
        runs=list(runs),
        gospa={s: np.array([r.gospa for r in by[s]]) for s in MANAGERS},
        decide_s={s: sum(r.decide_s for r in by[s]) / sum(r.epochs for r in by[s]) for s in by},
        candidates=candidates,
        missed={s: float(np.mean([r.missed for r in by[s]])) for s in MANAGERS},
        false={s: float(np.mean([r.false for r in by[s]])) for s in MANAGERS},
    )


def print_managers(scenario: Scenario, c: ManagerComparison) -> None:
    ev = scenario.evaluation
    print(
        f"# part 2: beam pointing on {scenario.name}, {len(c.runs)} paired runs (seed "
        f"{scenario.seed}, runs {c.runs[0]}..{c.runs[-1]}), {scenario.steps} epochs of "
        f"dt={scenario.dt:g} s, GOSPA c={ev.cutoff:g} m p={ev.order:g} alpha={ev.alpha:g}; "
        f"Stone Soup: BruteForceSensorManager + UncertaintyRewardFunction over <= "
        f"{c.candidates} pointings per beam, platforms holding course"
    )
    labels = {
        "planner": "activetrack planner (MRE manoeuvres + MRE beams)",
        "hold_course": "activetrack MRE beams, platforms hold course",
        "stonesoup": "Stone Soup manager beams, platforms hold course",
    }
    for s in MANAGERS:
        m, se = c.mean_se(s)
        ms = c.decide_s[s] * 1e3
        print(
            f"{labels[s]:<50} GOSPA {m:8.2f} +- {se:6.2f} m  (missed {c.missed[s]:4.2f}, "
            f"false {c.false[s]:5.2f} per epoch)  decision {ms:6.1f} ms/epoch"
        )
    for a in ("planner", "hold_course"):
        d = c.paired(a, "stonesoup")
        lower = "ours lower" if d.mean < 0 else "Stone Soup lower"
        verdict = "resolved" if d.resolved else "not resolved"
        print(
            f"GOSPA({a}) - GOSPA(stonesoup) = {d.mean:+.2f} m [{d.low:+.2f}, {d.high:+.2f}] "
            f"(paired, 95 %; {lower}, {verdict})"
        )


def _scale_module():
    """``benchmarks/multitarget_scale.py`` (the scale table's scenes and timing)."""
    return _sibling("multitarget_scale")


def _step_ms(rows, n: int) -> str:
    """Our median step (ms) at ``n`` spread targets and the lowest clutter, as the last line
    prints it (``over_budget`` / ``not_run``)."""
    for row in rows:
        if row.n_targets == n and row.layout == "spread":
            cell = row.cells["ours"]
            return f"{np.median(cell.times) * 1e3:.1f}" if cell.times else "over_budget"
    return "not_run"


def _pruned(rows, n: int) -> str:
    """JPDA clusters our step pruned at ``n`` spread targets and the lowest clutter (the
    figure of the last line)."""
    for row in rows:
        if row.n_targets == n and row.layout == "spread":
            return str(row.cells["ours"].pruned)
    return "not_run"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a smoke run of every part, ~1-2 min")
    p.add_argument("--runs", type=int_in_range(2, 1000), default=10,
                   help="paired runs of part 1 (the full trackers)")  # fmt: skip
    p.add_argument("--jpda-runs", type=int_in_range(2, 1000), default=10,
                   help="paired runs of part 1's bare jpda_update line")  # fmt: skip
    p.add_argument("--sizes", type=int, nargs="+", default=[3, 10, 30, 100, 300, 1000],
                   help="targets of the scale table")  # fmt: skip
    p.add_argument("--clutter", type=float, nargs="+", default=[10.0, 100.0, 1000.0],
                   help="false alarms per scan and radar of the scale table")  # fmt: skip
    p.add_argument("--budget", type=float, default=None,
                   help="POINT_BUDGET_S: wall time per implementation and point (s)")  # fmt: skip
    p.add_argument("--epochs", type=int_in_range(1, 100), default=5,
                   help="timed epochs per scale point")  # fmt: skip
    p.add_argument("--managers", action="store_true",
                   help="also part 2, the sensor managers (~30 min at 8 runs)")  # fmt: skip
    p.add_argument(
        "--manager-runs", type=int_in_range(2, 1000), default=DEFAULT_MANAGER_RUNS,
        help="paired runs of part 2",
    )  # fmt: skip
    p.add_argument(
        "--candidates", type=int_in_range(1, 20), default=DEFAULT_CANDIDATES,
        help="pointings per beam left to Stone Soup's brute force (part 2)",
    )  # fmt: skip
    p.add_argument("--jobs", type=int_in_range(1, 64), default=2, help="processes of part 2")
    args = p.parse_args(argv)
    try:
        import stonesoup
    except ImportError:
        print(
            "stonesoup is not installed: run `make bench`, or "
            ".venv/bin/python -m pip install -r requirements-bench.txt -c constraints.txt",
            file=sys.stderr,
        )
        return 1
    print(
        f"# multitarget benchmark  python {platform.python_version()}  numpy {np.__version__}"
        f"  stonesoup {stonesoup.__version__}"
    )
    print(f"# {_sibling('machine').describe()}")
    sc = JPDAScenario()
    scale = _scale_module()
    t_start = time.perf_counter()
    if args.quick:
        runs, jpda_runs, n_scans, epochs = 2, 2, 20, 3
        budget = scale.QUICK_BUDGET_S if args.budget is None else args.budget
        sizes, clutters, layouts = [3, 10, 30, 300, 1000], [10.0], ["spread"]
    else:
        runs, jpda_runs, n_scans, epochs = args.runs, args.jpda_runs, None, args.epochs
        budget = scale.POINT_BUDGET_S if args.budget is None else args.budget
        sizes, clutters, layouts = args.sizes, args.clutter, list(scale.LAYOUTS)
    trackers = compare_trackers([3000 + i for i in range(runs)], n_scans)
    print_trackers(trackers, n_scans or sc.n_steps)
    jpda = compare_jpda(sc, [2000 + i for i in range(jpda_runs)])
    print("# part 1, secondary: the bare association filter, no track management")
    print_jpda(sc, jpda)
    print(f"load average {os.getloadavg()[0]:.1f}")
    scale.print_header(list(scale.IMPLEMENTATIONS), epochs, budget)
    rows = scale.scale_table(
        sizes, layouts, sorted(clutters), list(scale.IMPLEMENTATIONS), budget, epochs,
        printer=scale.print_row,
    )  # fmt: skip
    print(f"load average {os.getloadavg()[0]:.1f}")
    crowded = check_crowded(sc)
    print_crowded(crowded)
    if args.managers:
        t_part2 = time.perf_counter()
        scenario_b = load_scenario(SCENARIO_B)
        managers = compare_managers(
            scenario_b, list(range(args.manager_runs)), args.candidates, args.jobs
        )
        print_managers(scenario_b, managers)
        d = managers.paired("planner", "stonesoup")
        print(f"# part 2 wall time {time.perf_counter() - t_part2:.1f} s")
        print(f"gospa_diff_vs_stonesoup_manager_m={d.mean:+.1f}[{d.low:+.1f},{d.high:+.1f}]")
    print(f"# benchmark wall time {time.perf_counter() - t_start:.1f} s")
    pruned = [str(trackers.pruned), _pruned(rows, 300), _pruned(rows, 1000), str(crowded.pruned)]
    exact = all(p in ("0", "not_run") for p in pruned)
    print(
        f"# JPDA clusters pruned behind the last line's figures (oversize_cluster: prune; 0: "
        f"exact JPDA everywhere): part 1 {pruned[0]}, n300 {pruned[1]}, n1000 {pruned[2]}, "
        f"crowded {pruned[3]}" + ("" if exact else "  NOT EXACT: the figures are approximate")
    )
    print(
        f"tracker_step_speedup_vs_stonesoup={trackers.paired_speedup:.2f} "
        f"n300_step_ms={_step_ms(rows, 300)} n1000_step_ms={_step_ms(rows, 1000)} "
        f"crowded10_gospa_equals_exact={str(crowded.equal).lower()}"
    )
    return 0


if __name__ == "__main__":
    # As the command line and the nodes do: the timings are those users get.
    tune_allocator()
    sys.exit(main())
