"""Multi-target tracking with track management, side by side with Stone Soup (issue 25).

Run with ``.venv/bin/python benchmarks/multitarget_tracking.py [--runs N] [--scenes ...]``
after ``make bench`` (Stone Soup is a bench-only dependency). The last line is
``tracker_gospa_vs_stonesoup=<scene>:<ours - theirs>,...``: the mean paired difference of the
time-averaged GOSPA [m] per scene (negative: ours lower).

Both trackers start from the same priors, see the same unlabelled scans and manage their own
tracks; GOSPA (c = 500 m, p = 2, alpha = 2) counts every track each reports (ours: the
confirmed ones; Stone Soup's initiator hands over only the tracks it confirmed).

- **ours**: :class:`activetrack.tracking.tracker.Tracker` with the EKF and the schema's
  default ``tracker.tracks`` (gate, M-of-N, existence, initiation from detections on);
- **theirs**: Stone Soup's ``JPDA`` (``PDAHypothesiser``, ``ExtendedKalmanPredictor``,
  ``PDAUpdater``, as the bare association filter of ``benchmarks/multitarget.py``, its gate
  at the scene's ``gate_sigmas``), a ``MultiMeasurementInitiator`` (GNN on the Mahalanobis
  distance, ``min points`` updates to confirm, velocity prior std ``init_speed_std`` as ours; its
  tentative tracks go after ``STONESOUP_TENTATIVE_MISSES`` scans without an update,
  ``UpdateTimeStepsDeleter``) and a ``CovarianceBasedDeleter`` on the confirmed tracks'
  position variances (threshold ``STONESOUP_DELETE_STD``^2 per axis).

Scenes (targets, motion, radar, clutter and crossing of the bare filter's scene of
``benchmarks/multitarget.py``, 3, 4, 5, 3, ... targets by run, 40 scans of 5 s):

- ``radar``: the one range-bearing radar at (14, 8) km looking west;
- ``bearings``: two bearing sensors, at (1, 8) km looking east and at (7, 1) km looking north
  (the lines of sight cross at about 90 degrees), sigma ``sigma_b``, clutter
  ``BEARING_CLUTTER`` per rad, 60 degree sectors. Neither tracker starts a track from a
  bearing (Stone Soup's initiator needs a reversible measurement model), so only the priors'
  tracks and their deletion count. Stone Soup 1.9's ``PDAUpdater`` fails on a one-component
  ``Bearing``-typed innovation (it multiplies a ``Probability`` by it), so its bearing model
  here returns plain floats; the sites keep every bearing far from the +-pi cut, where the
  plain difference is the wrapped one.

Each scene with two kinds of priors on the same worlds: ``drawn``, mean x0 + e with e ~
N(0, P0), and ``3sigma``, e = 3 P0^(1/2) u with u uniform on the unit sphere (Mahalanobis
distance exactly 3: a prior in the tail, about the worst 6 % of drawn ones in 4 dimensions).
Truth and scans come from ``default_rng([seed, 0])``, the priors from ``[seed, 1]``.

Measured (4 runs per scene, seeds 3000-3003; Stone Soup 1.9.1; a 2-core VM shared with other
jobs, load average ~8), time-averaged GOSPA, ours - theirs with its 95 % interval:

    radar_drawn      ours 172.1 m  Stone Soup 528.1 m  -356.1 [-462.8, -249.3] m
    radar_3sigma     ours 191.9 m  Stone Soup 538.4 m  -346.4 [-441.0, -251.9] m
    bearings_drawn   ours 267.0 m  Stone Soup 327.8 m   -60.8 [-173.8,  +52.1] m
    bearings_3sigma  ours 276.7 m  Stone Soup 316.8 m   -40.1 [-167.6,  +87.4] m

Stone Soup's radar GOSPA is dominated by confirmed clutter tracks (its initiator has no
probability of existence); on the bearings runs 0-1 the two agree to 0.4 m (the same maths,
no track deleted), its excess is in runs 2-3 (not examined: its 150 m covariance deleter,
set on the radar, may end bearings tracks). Wall time here ~2 min for ours, ~7 min for
Stone Soup's JPDA with its initiator over clutter.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from datetime import timedelta
from pathlib import Path

import numpy as np

from activetrack.data import Scan, TrackSet
from activetrack.filters.ekf import ExtendedKalmanFilter
from activetrack.metrics import gospa
from activetrack.models import NearlyConstantVelocity
from activetrack.models.clutter import ClutteredSensor
from activetrack.models.fov import FieldOfView
from activetrack.models.sensors import BearingSensor, RangeBearingSensor
from activetrack.montecarlo.paired import paired_difference
from activetrack.scenarios.schema import TrackManagementConfig
from activetrack.tracking.tracker import FilterSpec, Tracker, TrackPrior


def _load_part1():
    """``benchmarks/multitarget.py`` (its scene, conversions and Stone Soup JPDA)."""
    path = Path(__file__).resolve().parent / "multitarget.py"
    spec = importlib.util.spec_from_file_location("bench_multitarget", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(spec.name, module)  # dataclasses look their module up
    spec.loader.exec_module(module)
    return sys.modules[spec.name]


mt = _load_part1()
SC = mt.JPDAScenario()
SCENES = ("radar", "bearings")
PRIORS = ("drawn", "3sigma")
BEARING_CLUTTER = 3.0  # false alarms per rad (pi / 3 rad sector: 3.1 per scan)
# x, y [m] and look direction [rad] of the two bearing sensors: west of the crossing looking
# east and south of it looking north (bearings stay far from the +-pi cut, see module docstring)
BEARING_SITES = (("b1", 1000.0, 8000.0, 0.0), ("b2", 7000.0, 1000.0, math.pi / 2))
# Stone Soup's settings, the best of a small grid on radar_drawn runs 0-1 (delete std 150 /
# 250 m, 3 / 4 points: time-averaged GOSPA 778 / 731 m at 150 m and 3 points, 494 / 535 m at
# 150 m and 4, 708 m (run 0) at 250 m and 4): false tracks from clutter dominate its GOSPA.
STONESOUP_DELETE_STD = 150.0  # m per axis
STONESOUP_MIN_POINTS = 4  # updates that confirm a Stone Soup tentative track
STONESOUP_TENTATIVE_MISSES = 2  # scans without an update that delete a tentative track
_EPOCH = mt.EPOCH


@dataclass(frozen=True)
class SensorSite:
    """One stationary sensor: id, model in clutter, platform pv ``(4,)`` and field of view."""

    sensor_id: str
    sensor: ClutteredSensor
    pv: np.ndarray
    fov: FieldOfView


def sites(scene: str, gate_sigmas: float = SC.gate_sigmas) -> list[SensorSite]:
    """The scene's sensors (module docstring); ``gate_sigmas`` the association gate."""
    if scene not in SCENES:
        raise ValueError(f"scene: must be one of {SCENES}, got {scene!r}")
    radar_pv = np.array([SC.sensor_xy[0], 0.0, SC.sensor_xy[1], 0.0])
    r = (SC.r_min, SC.r_max)
    if scene == "radar":
        base = RangeBearingSensor(SC.sigma_r, SC.sigma_b, SC.pd, *r)
        sensor = ClutteredSensor(base, SC.clutter_density, gate_sigmas, SC.fov_centre, SC.fov_width)
        return [SensorSite("radar", sensor, radar_pv, sensor.field_of_view(radar_pv))]
    out = []
    for sid, x, y, centre in BEARING_SITES:
        base = BearingSensor(SC.sigma_b, SC.pd, *r)
        sensor = ClutteredSensor(base, BEARING_CLUTTER, gate_sigmas)
        pv = np.array([x, 0.0, y, 0.0])
        out.append(SensorSite(sid, sensor, pv, FieldOfView(centre, SC.fov_width, *r)))
    return out


@dataclass
class World:
    """One seeded run of a scene: truth ``(K + 1, n, 4)``, prior means ``(n, 4)`` and
    covariance ``(4, 4)``, and per scan 1..K one array ``(m, dim_z)`` per site."""

    seed: int
    truth: np.ndarray
    prior_means: np.ndarray
    prior_cov: np.ndarray
    scans: list[list[np.ndarray]]


def simulate(scene: str, priors: str, seed: int, n_targets: int) -> World:
    """Truth and scans from ``default_rng([seed, 0])``, priors from ``[seed, 1]`` (so that
    ``drawn`` and ``3sigma`` share the world)."""
    if priors not in PRIORS:
        raise ValueError(f"priors: must be one of {PRIORS}, got {priors!r}")
    rng = np.random.default_rng([seed, 0])
    model = NearlyConstantVelocity(SC.q)
    x = mt.initial_states(SC, n_targets)
    truth = [x]
    for _ in range(SC.n_steps):
        x = model.sample(x, SC.T, rng)
        truth.append(x)
    scans = []
    for k in range(1, SC.n_steps + 1):
        row = []
        for site in sites(scene):
            X = truth[k][site.fov.contains(truth[k], site.pv)]
            seen = X[site.sensor.detect(X, site.pv, rng)]
            Z = np.concatenate(
                [site.sensor.sample(seen, site.pv, rng), site.sensor.sample_clutter(site.fov, rng)]
            )
            row.append(Z[rng.permutation(len(Z))])
        scans.append(row)
    std = np.asarray(SC.prior_std)
    prior_rng = np.random.default_rng([seed, 1])
    u = prior_rng.standard_normal((n_targets, 4))
    if priors == "3sigma":
        u *= 3.0 / np.linalg.norm(u, axis=1, keepdims=True)
    return World(seed, np.array(truth), truth[0] + u * std, np.diag(std**2), scans)


@dataclass
class Stepper:
    """A tracker set up on one world: ``step(k)`` runs scan k (1..K), everything the tracker
    does with it (``benchmarks/multitarget.py`` times this call); ``positions()`` the
    positions ``(n, 2)`` of the tracks it reports after the last step (not timed)."""

    step: Callable[[int], None]
    positions: Callable[[], np.ndarray]
    pruned: Callable[[], int] = lambda: 0  # JPDA clusters pruned so far (ours: its counter)


def run(stepper: Stepper, n_scans: int) -> list[np.ndarray]:
    """The stepper's reported positions at scans 1..``n_scans``."""
    out = []
    for k in range(1, n_scans + 1):
        stepper.step(k)
        out.append(stepper.positions())
    return out


def ours(scene: str, world: World) -> Stepper:
    """Our tracker with the EKF and the default ``tracker.tracks`` but ``oversize_cluster:
    prune`` (the same bits while every cluster's exact JPDA fits; its pruned clusters counted)
    (its confirmed tracks reported); the scans are built beforehand."""
    cfg = TrackManagementConfig(oversize_cluster="prune")
    model = NearlyConstantVelocity(SC.q)
    scene_sites = sites(scene, cfg.gate_sigmas)

    def make(x0: np.ndarray, P0: np.ndarray, t0: float) -> ExtendedKalmanFilter:
        return ExtendedKalmanFilter(model, x0, P0, t0)

    tracker = Tracker(
        model,
        "ncv",
        FilterSpec("ekf", False, make),
        {s.sensor_id: s.sensor for s in scene_sites},
        [TrackPrior(f"t{i}", m, world.prior_cov) for i, m in enumerate(world.prior_means)],
        known_association=False,
        management=cfg,
        planner_samples=1,
        new_track_priority=1.0,
        rng=np.random.default_rng(world.seed),
    )
    scans = [
        [
            Scan(s.sensor_id, k, k * SC.T, s.pv, Z, s.fov)
            for s, Z in zip(scene_sites, row, strict=True)
        ]
        for k, row in enumerate(world.scans, start=1)
    ]
    last: list[TrackSet] = []

    def step(k: int) -> None:
        last[:] = [tracker.step(k, k * SC.T, scans[k - 1])]

    def positions() -> np.ndarray:
        return np.array([tr.mean[[0, 2]] for tr in last[0].confirmed]).reshape(-1, 2)

    return Stepper(step, positions, lambda: tracker.pruning.clusters)


def run_ours(scene: str, world: World) -> list[np.ndarray]:
    """Our tracker (:func:`ours`): the confirmed tracks' positions ``(n_k, 2)`` at scans 1..K."""
    return run(ours(scene, world), len(world.scans))


def _stonesoup_model(site: SensorSite):
    """Stone Soup's measurement model of a site (bearing, range) or bearing."""
    from stonesoup.models.measurement.nonlinear import Cartesian2DToBearing
    from stonesoup.types.array import StateVector

    class FloatBearing(Cartesian2DToBearing):
        """Bearings as plain floats (module docstring: Stone Soup's PDA updater)."""

        @staticmethod
        def _typed_vector():
            return np.array([[0.0]])

    if site.sensor.base.kind == "range_bearing":
        return mt._stonesoup_measurement_model(SC, site.pv)
    return FloatBearing(
        ndim_state=4,
        mapping=(0, 2),
        noise_covar=np.array([[SC.sigma_b**2]]),
        translation_offset=StateVector([site.pv[0], site.pv[2]]),
    )


def _stonesoup_detections(site: SensorSite, model, Z: np.ndarray, when) -> set:
    from stonesoup.types.angle import Bearing
    from stonesoup.types.array import StateVector
    from stonesoup.types.detection import Detection

    if site.sensor.base.kind == "range_bearing":  # ours (range, bearing)
        vectors = [StateVector([Bearing(b), r]) for r, b in Z]
    else:
        vectors = [StateVector([float(b)]) for (b,) in Z]
    return {Detection(v, timestamp=when, measurement_model=model) for v in vectors}


def _stonesoup_initiator(model, deleter):
    """Stone Soup's two-point initiator on a radar (module docstring)."""
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
    from stonesoup.hypothesiser.distance import DistanceHypothesiser
    from stonesoup.initiator.simple import MultiMeasurementInitiator
    from stonesoup.measures import Mahalanobis
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
    )
    from stonesoup.predictor.kalman import ExtendedKalmanPredictor
    from stonesoup.types.array import CovarianceMatrix, StateVector
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import ExtendedKalmanUpdater

    v = TrackManagementConfig().init_speed_std
    predictor = ExtendedKalmanPredictor(
        CombinedLinearGaussianTransitionModel([ConstantVelocity(SC.q), ConstantVelocity(SC.q)])
    )
    updater = ExtendedKalmanUpdater(model)
    hypothesiser = DistanceHypothesiser(
        predictor, updater, measure=Mahalanobis(), missed_distance=SC.gate_sigmas
    )
    return MultiMeasurementInitiator(
        prior_state=GaussianState(
            StateVector([0.0, 0.0, 0.0, 0.0]), CovarianceMatrix(np.diag([0.0, v**2, 0.0, v**2]))
        ),
        measurement_model=model,
        deleter=deleter,
        data_associator=GNNWith2DAssignment(hypothesiser),
        updater=updater,
        min_points=STONESOUP_MIN_POINTS,
    )


def stonesoup(scene: str, world: World) -> Stepper:
    """Stone Soup's JPDA with its initiator and deleter (module docstring), all its tracks
    reported; its detections are built beforehand."""
    from stonesoup.deleter.error import CovarianceBasedDeleter
    from stonesoup.deleter.time import UpdateTimeStepsDeleter
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track

    scene_sites = sites(scene)
    models = [_stonesoup_model(s) for s in scene_sites]
    jpdas = []
    for s, m in zip(scene_sites, models, strict=True):
        jpdas.append(mt._stonesoup_jpda(replace(SC, clutter_density=s.sensor.clutter_density), m))
    deleter = CovarianceBasedDeleter(covar_trace_thresh=2 * STONESOUP_DELETE_STD**2, mapping=[0, 2])
    radar = scene_sites[0].sensor.base.kind == "range_bearing"
    # Tentative tracks go after two scans without an update (a covariance threshold would hold
    # every clutter detection's track for ~10 scans: hundreds of them).
    tentative_deleter = UpdateTimeStepsDeleter(time_steps_since_update=STONESOUP_TENTATIVE_MISSES)
    initiator = _stonesoup_initiator(models[0], tentative_deleter) if radar else None
    tracks = {
        Track([GaussianState(m.reshape(4, 1), world.prior_cov, timestamp=_EPOCH)])
        for m in world.prior_means
    }
    whens = [_EPOCH + timedelta(seconds=SC.T * k) for k in range(1, len(world.scans) + 1)]
    detections = [
        [_stonesoup_detections(site, model, Z, when)
         for site, model, Z in zip(scene_sites, models, row, strict=True)]
        for row, when in zip(world.scans, whens, strict=True)
    ]  # fmt: skip

    def step(k: int) -> None:
        nonlocal tracks
        when = whens[k - 1]
        for (associator, updater), dets in zip(jpdas, detections[k - 1], strict=True):
            hypotheses = associator.associate(tracks, dets, when)
            used = set()
            for track in tracks:
                track.append(updater.update(hypotheses[track]))
                used |= {h.measurement for h in hypotheses[track] if h}
            tracks -= deleter.delete_tracks(tracks)
            if initiator is not None:
                tracks |= initiator.initiate(dets - used, when)

    def positions() -> np.ndarray:
        return np.array(
            [np.asarray(t.state_vector, dtype=float)[[0, 2], 0] for t in tracks]
        ).reshape(-1, 2)

    return Stepper(step, positions)


def run_stonesoup(scene: str, world: World) -> list[np.ndarray]:
    """Stone Soup's tracker (:func:`stonesoup`): the positions of its tracks ``(n_k, 2)`` at
    scans 1..K."""
    return run(stonesoup(scene, world), len(world.scans))


def mean_gospa(world: World, positions: list[np.ndarray]) -> float:
    """Time-averaged GOSPA (c = ``SC.cutoff``, p = ``SC.order``, alpha = 2) over scans 1..K."""
    return float(
        np.mean(
            [
                gospa(world.truth[k][:, [0, 2]], Y, SC.cutoff, SC.order).distance
                for k, Y in enumerate(positions, start=1)
            ]
        )
    )


@dataclass
class SceneResult:
    """Per-run time-averaged GOSPA [m] of ours and theirs on one scene and kind of prior."""

    scene: str
    priors: str
    seeds: list[int]
    ours: np.ndarray
    theirs: np.ndarray
    seconds: tuple[float, float]

    @property
    def name(self) -> str:
        return f"{self.scene}_{self.priors}"


def compare(scene: str, priors: str, seeds: list[int]) -> SceneResult:
    """Both trackers on the same worlds (3, 4, 5, 3, ... targets by run)."""
    ours, theirs, wall = [], [], [0.0, 0.0]
    for i, seed in enumerate(seeds):
        world = simulate(scene, priors, seed, 3 + i % 3)
        for j, (fn, into) in enumerate(((run_ours, ours), (run_stonesoup, theirs))):
            start = time.perf_counter()
            into.append(mean_gospa(world, fn(scene, world)))
            wall[j] += time.perf_counter() - start
    return SceneResult(scene, priors, seeds, np.array(ours), np.array(theirs), tuple(wall))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=20, help="seeded runs per scene")
    p.add_argument("--scenes", nargs="+", choices=SCENES, default=list(SCENES))
    args = p.parse_args(argv)
    try:
        import stonesoup
    except ImportError:
        print("stonesoup is not installed: run `make bench`", file=sys.stderr)
        return 1
    print(
        f"# tracking with track management, ours vs Stone Soup {stonesoup.__version__}: "
        f"{args.runs} runs per scene, {SC.n_steps} scans of {SC.T:g} s, GOSPA c={SC.cutoff:g} "
        f"m p={SC.order:g} alpha=2"
    )
    diffs = []
    seeds = [3000 + i for i in range(args.runs)]
    for scene in args.scenes:
        for priors in PRIORS:
            r = compare(scene, priors, seeds)
            d = paired_difference(r.ours, r.theirs)
            print(
                f"{r.name:<16} ours {r.ours.mean():7.1f} m  Stone Soup {r.theirs.mean():7.1f} m  "
                f"ours - theirs {d.mean:+7.1f} [{d.low:+7.1f}, {d.high:+7.1f}] m  "
                f"({r.seconds[0]:.0f} s / {r.seconds[1]:.0f} s)"
            )
            diffs.append(f"{r.name}:{d.mean:.1f}")
    print("tracker_gospa_vs_stonesoup=" + ",".join(diffs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
