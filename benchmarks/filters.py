"""Filter speed and accuracy against Stone Soup and filterpy on identical seeded data.

Run with ``make bench`` (installs Stone Soup from ``requirements-bench.txt``) or directly as
``.venv/bin/python benchmarks/filters.py [--quick]``.

Scenario (after Hernandez sec. 5.1): bearings-only tracking of a nearly-constant-velocity
target, state (x, xdot, y, ydot), epochs every T = 5 s for 30 epochs (150 s), bearing noise
sigma = 0.01 rad, one sensor starting at (1800, 2000) m with velocity (-40, -40) m/s that turns
left by pi/10 at every epoch (Hernandez's largest manoeuvre) at constant speed, so it circles
(radius about 900 m) and keeps the target observable. The target starts near (0, 0) moving at
(8, 6) m/s, prior N(m0, C0) with C0 = diag(400, 1, 400, 1) (Hernandez's target moves with
the sensor's own velocity; with a scripted sensor that makes a poor test case). Process noise
PSD q = 0.01 m^2/s^3 instead of Hernandez's 1e-8: with 1e-8 an always-resampling SIR filter
keeps almost no distinct particles. The minimum detection range is not used (every epoch has
a detection), since Stone Soup's SIR updater has no non-detection likelihood.

Each Monte Carlo run draws the true x_0 ~ N(m0, C0), the trajectory and the bearings from one
seeded numpy Generator; every implementation filters the very same bearings from the same
prior. The particle filters also start from the same initial particle cloud (their later
random draws differ, which is what the Monte Carlo error covers).

Our PF runs on the compiled kernels (``activetrack.kernels``, numba) from the first step; its
numpy path, the kernels' reference, is timed as well on the Stone Soup runs (same numbers, so
its RMSE difference is exactly zero).

Timing: time.perf_counter around each predict + update (estimate extraction excluded), over
all steps of all runs after a warm-up run; the median per-step time is reported. The
implementations take turns run by run (alternating order); each speed ratio is the median
over the runs both did of the per-run paired ratio (their median step / ours in that run),
with its 10th and 90th percentiles. Detections
(ours: ``Measurement``, Stone Soup: ``Detection`` with a per-epoch measurement model) are built
before timing for every implementation.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import platform
import statistics
import sys
import time
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

from activetrack import kernels
from activetrack.allocator import tune_allocator
from activetrack.angles import wrap_angle
from activetrack.bounds.pcrlb import measurement_information, pcrlb_step
from activetrack.filters import ExtendedKalmanFilter, Measurement, ParticleFilter
from activetrack.models import BearingSensor, NearlyConstantVelocity


@dataclass(frozen=True)
class Scenario:
    T: float = 5.0  # s between epochs (Hernandez sec. 5.1)
    n_steps: int = 30  # 150 s
    q: float = 0.01  # process noise PSD, m^2/s^3
    sigma: float = 0.01  # bearing noise, rad (Hernandez sec. 5.1)
    m0: tuple = (0.0, 8.0, 0.0, 6.0)  # prior mean (x, xdot, y, ydot)
    C0: tuple = (400.0, 1.0, 400.0, 1.0)  # prior covariance diagonal
    sensor0: tuple = (1800.0, -40.0, 2000.0, -40.0)  # Hernandez eq. 17
    turn: float = math.pi / 10  # sensor heading change per epoch (Hernandez's maximum)


@dataclass
class Run:
    """One seeded Monte Carlo run: truth and sensor pv at epochs 0..K, bearings at 1..K."""

    seed: int
    truth: np.ndarray  # (K + 1, 4)
    sensor: np.ndarray  # (K + 1, 4)
    z: np.ndarray  # (K,)
    times: np.ndarray  # (K,) measurement times k T


def sensor_path(sc: Scenario) -> np.ndarray:
    """Sensor pv at epochs 0..K: it turns left by ``sc.turn`` at every epoch, speed kept."""
    s = np.array(sc.sensor0, dtype=float)
    out = [s]
    c, d = math.cos(sc.turn), math.sin(sc.turn)
    for _ in range(sc.n_steps):
        v = np.array([c * s[1] - d * s[3], d * s[1] + c * s[3]])
        s = np.array([s[0] + sc.T * v[0], v[0], s[2] + sc.T * v[1], v[1]])
        out.append(s)
    return np.array(out)


def simulate(sc: Scenario, seed: int) -> Run:
    rng = np.random.default_rng(seed)
    model = NearlyConstantVelocity(sc.q)
    sensor_model = BearingSensor(sc.sigma)
    m0, C0 = np.array(sc.m0), np.diag(sc.C0)
    x = m0 + np.linalg.cholesky(C0) @ rng.standard_normal(4)
    truth = [x]
    for _ in range(sc.n_steps):
        x = model.sample(x, sc.T, rng)
        truth.append(x)
    truth, sensor = np.array(truth), sensor_path(sc)
    z = sensor_model.sample(truth[1:], sensor[1:], rng)[:, 0]
    times = sc.T * np.arange(1, sc.n_steps + 1)
    return Run(seed, truth, sensor, z, times)


def initial_particles(sc: Scenario, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng([seed, 1])
    return np.array(sc.m0) + rng.standard_normal((n, 4)) * np.sqrt(sc.C0)


# --- the implementations: each returns (estimates (K, 4), per-step times (K,)) --------------


def run_ours_ekf(sc: Scenario, run: Run, **_):
    model, sensor = NearlyConstantVelocity(sc.q), BearingSensor(sc.sigma)
    meas = [
        [Measurement(sensor, run.sensor[k + 1], [run.z[k]], run.times[k])]
        for k in range(sc.n_steps)
    ]
    f = ExtendedKalmanFilter(model, np.array(sc.m0), np.diag(sc.C0))
    est, dt = np.empty((sc.n_steps, 4)), np.empty(sc.n_steps)
    clock = time.perf_counter
    for k in range(sc.n_steps):
        t0 = clock()
        f.step(run.times[k], meas[k])
        dt[k] = clock() - t0
        est[k] = f.mean
    return est, dt


def run_ours_pf_numpy(sc: Scenario, run: Run, n_particles: int, **_):
    """Our PF on the numpy path (the reference of the compiled kernels; same numbers)."""
    kernels.set_kernels("numpy")
    try:
        return run_ours_pf(sc, run, n_particles)
    finally:
        kernels.set_kernels("compiled")


def run_ours_pf(sc: Scenario, run: Run, n_particles: int, **_):
    model, sensor = NearlyConstantVelocity(sc.q), BearingSensor(sc.sigma)
    meas = [
        [Measurement(sensor, run.sensor[k + 1], [run.z[k]], run.times[k])]
        for k in range(sc.n_steps)
    ]
    f = ParticleFilter(
        model,
        particles=initial_particles(sc, n_particles, run.seed),
        rng=np.random.default_rng([run.seed, 2]),
        resample="always",
    )
    est, dt = np.empty((sc.n_steps, 4)), np.empty(sc.n_steps)
    clock = time.perf_counter
    for k in range(sc.n_steps):
        t0 = clock()
        f.step(run.times[k], meas[k])
        dt[k] = clock() - t0
        est[k] = f.mean
    return est, dt


def run_filterpy_ekf(sc: Scenario, run: Run, **_):
    from filterpy.kalman import ExtendedKalmanFilter as FPEKF

    model = NearlyConstantVelocity(sc.q)
    f = FPEKF(dim_x=4, dim_z=1)
    f.x = np.array(sc.m0).reshape(4, 1)
    f.P = np.diag(sc.C0)
    f.F = model.transition_matrix(sc.T)
    f.Q = model.process_noise(sc.T)
    f.R = np.array([[sc.sigma**2]])

    def hx(x, s):
        return np.array([[math.atan2(x[2, 0] - s[2], x[0, 0] - s[0])]])

    def H_jacobian(x, s):
        dx, dy = x[0, 0] - s[0], x[2, 0] - s[2]
        r2 = dx * dx + dy * dy
        return np.array([[-dy / r2, 0.0, dx / r2, 0.0]])

    def residual(a, b):
        return wrap_angle(a - b)

    zs = [np.array([[z]]) for z in run.z]
    est, dt = np.empty((sc.n_steps, 4)), np.empty(sc.n_steps)
    clock = time.perf_counter
    for k in range(sc.n_steps):
        s = run.sensor[k + 1]
        t0 = clock()
        f.predict()
        f.update(zs[k], H_jacobian, hx, args=(s,), hx_args=(s,), residual=residual)
        dt[k] = clock() - t0
        est[k] = f.x[:, 0]
    return est, dt


def _stonesoup_models(sc: Scenario, seed: int | None = None):
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
    )

    # Same Q as NearlyConstantVelocity: q * [[T^3/3, T^2/2], [T^2/2, T]] per axis, state
    # ordered (x, vx, y, vy) as ours.
    return CombinedLinearGaussianTransitionModel(
        [ConstantVelocity(sc.q), ConstantVelocity(sc.q)], seed=seed
    )


_EPOCH = datetime(2024, 1, 1)


def _stonesoup_detections(sc: Scenario, run: Run):
    """One Detection per epoch, each carrying its own Cartesian2DToBearing model.

    Stone Soup's bearing is atan2(y - y_s, x - x_s) after the translation offset and the
    rotation (zero here), typed ``Bearing`` so residuals wrap to [-pi, pi): the same convention
    as ours. The moving sensor is handled by a measurement model per epoch whose
    translation_offset is the sensor position at that epoch (the velocity does not enter a
    bearing).
    """
    from stonesoup.models.measurement.nonlinear import Cartesian2DToBearing
    from stonesoup.types.angle import Bearing
    from stonesoup.types.array import StateVector
    from stonesoup.types.detection import Detection

    dets = []
    for k in range(sc.n_steps):
        s = run.sensor[k + 1]
        mm = Cartesian2DToBearing(
            ndim_state=4,
            mapping=(0, 2),
            noise_covar=np.array([[sc.sigma**2]]),
            translation_offset=StateVector([s[0], s[2]]),
        )
        dets.append(
            Detection(
                StateVector([Bearing(run.z[k])]),
                timestamp=_EPOCH + timedelta(seconds=float(run.times[k])),
                measurement_model=mm,
            )
        )
    return dets


def run_stonesoup_ekf(sc: Scenario, run: Run, joseph: bool = False, **_):
    from stonesoup.predictor.kalman import ExtendedKalmanPredictor
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import ExtendedKalmanUpdater

    predictor = ExtendedKalmanPredictor(_stonesoup_models(sc))
    # Its default update form P - K S K^T (faster than its Joseph option, which evaluates the
    # numerical Jacobian a second time); symmetrised like ours.
    updater = ExtendedKalmanUpdater(
        measurement_model=None, force_symmetric_covariance=True, use_joseph_cov=joseph
    )
    dets = _stonesoup_detections(sc, run)
    state = GaussianState(np.array(sc.m0).reshape(4, 1), np.diag(sc.C0), timestamp=_EPOCH)
    est, dt = np.empty((sc.n_steps, 4)), np.empty(sc.n_steps)
    clock = time.perf_counter
    for k in range(sc.n_steps):
        det = dets[k]
        t0 = clock()
        prediction = predictor.predict(state, timestamp=det.timestamp)
        state = updater.update(SingleHypothesis(prediction, det))
        dt[k] = clock() - t0
        est[k] = np.asarray(state.state_vector, dtype=float)[:, 0]
    return est, dt


def run_stonesoup_ekf_joseph(sc: Scenario, run: Run, **_):
    return run_stonesoup_ekf(sc, run, joseph=True)


def run_stonesoup_pf(sc: Scenario, run: Run, n_particles: int, **_):
    from stonesoup.predictor.particle import ParticlePredictor
    from stonesoup.resampler.particle import SystematicResampler
    from stonesoup.types.array import StateVectors
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.state import ParticleState
    from stonesoup.updater.particle import ParticleUpdater

    # SystematicResampler draws from numpy's global state; seed it for a repeatable run.
    np.random.seed(run.seed % 2**32)  # noqa: NPY002
    predictor = ParticlePredictor(_stonesoup_models(sc, seed=run.seed % 2**32))
    updater = ParticleUpdater(measurement_model=None, resampler=SystematicResampler())
    dets = _stonesoup_detections(sc, run)
    X0 = initial_particles(sc, n_particles, run.seed)
    state = ParticleState(
        StateVectors(X0.T),
        log_weight=np.full(n_particles, -math.log(n_particles)),
        timestamp=_EPOCH,
    )
    est, dt = np.empty((sc.n_steps, 4)), np.empty(sc.n_steps)
    clock = time.perf_counter
    for k in range(sc.n_steps):
        det = dets[k]
        t0 = clock()
        prediction = predictor.predict(state, timestamp=det.timestamp)
        state = updater.update(SingleHypothesis(prediction, det))
        dt[k] = clock() - t0
        est[k] = np.asarray(state.mean, dtype=float)[:, 0]
    return est, dt


# --- measurement ---------------------------------------------------------------------------


@dataclass
class Result:
    name: str
    step_times: np.ndarray  # all timed steps (s)
    sq_err: np.ndarray  # (runs, K) squared position error
    seeds: list

    @property
    def median_step(self) -> float:
        return float(np.median(self.step_times))

    @property
    def rmse(self) -> float:
        return math.sqrt(float(np.mean(self.sq_err)))

    @property
    def rmse_se(self) -> float:
        """MC standard error of the RMSE from the per-run mean squared errors (delta method)."""
        per_run = self.sq_err.mean(axis=1)
        if per_run.size < 2:
            return math.nan
        se_mse = per_run.std(ddof=1) / math.sqrt(per_run.size)
        return se_mse / (2.0 * self.rmse)


def measure(impls, sc: Scenario, runs: list[Run], **kw) -> list[Result]:
    """Run every implementation ``(name, fn, n_runs)`` on the first ``n_runs`` runs.

    The implementations take turns run by run (in alternating order), so a change in the
    machine's background load hits them alike.
    """
    for _, fn, _ in impls:
        fn(sc, runs[0], **kw)  # warm-up (imports, caches, numpy code paths)
    times = {name: [] for name, _, _ in impls}
    errs = {name: [] for name, _, _ in impls}
    for i, run in enumerate(runs):
        order = impls if i % 2 == 0 else impls[::-1]
        for name, fn, n_runs in order:
            if i >= n_runs:
                continue
            est, dt = fn(sc, run, **kw)
            times[name].append(dt)
            d = est - run.truth[1:]
            errs[name].append(d[:, 0] ** 2 + d[:, 2] ** 2)
    return [
        Result(
            name,
            np.concatenate(times[name]),
            np.array(errs[name]),
            [r.seed for r in runs[:n_runs]],
        )
        for name, _, n_runs in impls
    ]


def paired_rmse_diff(a: Result, b: Result) -> tuple[float, float, int]:
    """RMSE(a) - RMSE(b) on the runs both did, with its paired MC standard error."""
    common = [s for s in a.seeds if s in b.seeds]
    ia = [a.seeds.index(s) for s in common]
    ib = [b.seeds.index(s) for s in common]
    ma, mb = a.sq_err[ia].mean(axis=1), b.sq_err[ib].mean(axis=1)
    ra, rb = math.sqrt(ma.mean()), math.sqrt(mb.mean())
    # Delta method on (mean ma, mean mb): d(ra - rb) = dma / (2 ra) - dmb / (2 rb).
    g = ma / (2 * ra) - mb / (2 * rb)
    se = g.std(ddof=1) / math.sqrt(len(common)) if len(common) > 1 else math.nan
    return ra - rb, se, len(common)


def paired_ratios(theirs: Result, ours: Result, n_steps: int) -> np.ndarray:
    """(their / our) median step time run by run, over the runs both did (both start at the
    first run and took turns on each, so a run's two times share the machine's load)."""
    n = min(len(theirs.seeds), len(ours.seeds))
    a = np.median(theirs.step_times.reshape(-1, n_steps)[:n], axis=1)
    b = np.median(ours.step_times.reshape(-1, n_steps)[:n], axis=1)
    return a / b


def paired_speedup(theirs: Result, ours: Result, n_steps: int) -> tuple[float, float, float]:
    """The headline ratio: the median over the common runs of the per-run paired ratios
    (:func:`paired_ratios`), with their 10th and 90th percentiles."""
    r = paired_ratios(theirs, ours, n_steps)
    med, lo, hi = np.percentile(r, [50, 10, 90])
    return float(med), float(lo), float(hi)


def time_pcrlb_step(sc: Scenario, n_mc: int, n_candidates: int, reps: int) -> float:
    """Median time of one PCRLB step (Hernandez eq. 3 with eq. 8-9) for many candidates."""
    rng = np.random.default_rng(7)
    model, sensor = NearlyConstantVelocity(sc.q), BearingSensor(sc.sigma)
    F, Q = model.transition_matrix(sc.T), model.process_noise(sc.T)
    X = np.array(sc.m0) + rng.standard_normal((n_mc, 4)) * np.sqrt(sc.C0)
    # Candidate headings for the next epoch around the current one (Hernandez sec. 5.1: turns
    # up to pi/10 per epoch), speed 56.6 m/s.
    s0 = np.array(sc.sensor0)
    heading = math.atan2(s0[3], s0[1]) + np.linspace(-math.pi / 10, math.pi / 10, n_candidates)
    v = math.hypot(s0[1], s0[3])
    cand = np.stack(
        [
            s0[0] + sc.T * v * np.cos(heading),
            v * np.cos(heading),
            s0[2] + sc.T * v * np.sin(heading),
            v * np.sin(heading),
        ],
        axis=-1,
    )
    J = np.broadcast_to(np.linalg.inv(np.diag(sc.C0)), (n_candidates, 4, 4))
    samples = X @ F.T
    out = []
    for _ in range(reps + 3):
        t0 = time.perf_counter()
        J_Z = measurement_information(sensor, cand, samples)
        pcrlb_step(J, F, Q, J_Z)
        out.append(time.perf_counter() - t0)
    return statistics.median(out[3:])


def _machine():
    """``benchmarks/machine.py`` (this file is also loaded by path, from the tests)."""
    path = Path(__file__).resolve().parent / "machine.py"
    spec = importlib.util.spec_from_file_location("bench_machine", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def us(t: float) -> str:
    return f"{t * 1e6:9.1f} us"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="few runs, a smoke check (~5 s)")
    p.add_argument("--particles", type=int, default=10_000)
    p.add_argument(
        "--pf-only",
        action="store_true",
        help="the particle filters alone (pf_speedup_vs_stonesoup in about half the time)",
    )
    args = p.parse_args(argv)

    sc = Scenario()
    # Our PF on the compiled kernels from the first step (the default "auto" mode switches to
    # them after a first stretch of work, activetrack.kernels); its numpy path is measured too.
    kernels.set_kernels("compiled")
    if args.quick:
        n_ekf, n_pf, n_ss_pf, pcrlb_reps = 20, 6, 3, 50
    else:
        n_ekf, n_pf, n_ss_pf, pcrlb_reps = 500, 200, 100, 500
    if args.pf_only:
        n_ekf = 0
    seeds = [1000 + i for i in range(max(n_ekf, n_pf))]
    runs = [simulate(sc, s) for s in seeds]
    N = args.particles

    print(f"# filters benchmark  python {platform.python_version()}  numpy {np.__version__}")
    print(f"# {_machine().describe()}")
    try:
        import stonesoup

        print(f"# stonesoup {stonesoup.__version__}", end="")
    except ImportError:
        print(
            "\nstonesoup is not installed: run `make bench`, or "
            ".venv/bin/python -m pip install -r requirements-bench.txt -c constraints.txt",
            file=sys.stderr,
        )
        return 1
    import filterpy

    print(f"  filterpy {filterpy.__version__}")
    print(
        f"# scenario: T={sc.T} s, {sc.n_steps} epochs, q={sc.q} m^2/s^3, sigma={sc.sigma} rad, "
        f"m0={sc.m0}, C0=diag{sc.C0}, sensor0={sc.sensor0}"
    )
    print(
        f"# Monte Carlo runs: EKFs {n_ekf}, our PF {n_pf}, Stone Soup PF and our PF's numpy "
        f"path {n_ss_pf} (the first {n_ss_pf} of ours: the slow ones get fewer); PF particles {N}"
    )
    print()

    t_start = time.perf_counter()
    ekf_impls = [
        ("activetrack EKF", run_ours_ekf, n_ekf),
        ("Stone Soup EKF", run_stonesoup_ekf, n_ekf),
        ("Stone Soup EKF (Joseph)", run_stonesoup_ekf_joseph, n_ekf),
        ("filterpy EKF", run_filterpy_ekf, n_ekf),
    ]
    ekf = measure(ekf_impls, sc, runs[:n_ekf]) if n_ekf else []
    pf = measure(
        [
            ("activetrack PF", run_ours_pf, n_pf),
            ("activetrack PF (numpy)", run_ours_pf_numpy, n_ss_pf),
            ("Stone Soup PF", run_stonesoup_pf, n_ss_pf),
        ],
        sc,
        runs[:n_pf],
        n_particles=N,
    )

    print("per-step time (predict + update, median over all steps of all runs)")
    print(f"{'implementation':<26} {'median':>12} {'p10':>12} {'p90':>12}  runs  RMSE +- MC SE (m)")
    for r in ekf + pf:
        p10, p90 = np.percentile(r.step_times, [10, 90])
        print(
            f"{r.name:<26} {us(r.median_step)} {us(p10)} {us(p90)}  {len(r.seeds):4d}  "
            f"{r.rmse:8.2f} +- {r.rmse_se:.2f}"
        )
    print()

    ours_pf, ours_pf_numpy, ss_pf = pf
    print(
        "speed ratios: run by run, their median step time / ours in the same run (the two "
        "took turns); the median of those paired ratios [p10, p90], and the ratio of the "
        "medians over all steps of those runs"
    )

    def verdict(x, target):
        return f"(target >= {target}x: {'met' if x >= target else 'MISSED'})"

    def line(label, theirs, ours, target=None):
        x, lo, hi = paired_speedup(theirs, ours, sc.n_steps)
        n = min(len(theirs.seeds), len(ours.seeds))
        steps = n * sc.n_steps  # the common runs' steps, the first ones of each
        pooled = np.median(theirs.step_times[:steps]) / np.median(ours.step_times[:steps])
        extra = verdict(x, target) if target else ""
        print(
            f"  {label:<30} {x:6.1f}x  [{lo:5.1f}, {hi:5.1f}]  {n:4d} runs  "
            f"(medians {pooled:5.1f}x)  {extra}".rstrip()
        )
        return x

    pairs = [(ours_pf, ss_pf), (ours_pf, ours_pf_numpy)]
    ekf_speedup = None
    if ekf:
        ours_ekf, ss_ekf, ss_ekf_j, fp_ekf = ekf
        ekf_speedup = line("EKF vs Stone Soup EKF", ss_ekf, ours_ekf, 30)
        line("EKF vs Stone Soup EKF (Joseph)", ss_ekf_j, ours_ekf)
        line("EKF vs filterpy EKF", fp_ekf, ours_ekf)
        pairs = [(ours_ekf, ss_ekf), (ours_ekf, fp_ekf), *pairs]
    pf_speedup = line("PF vs Stone Soup SIR PF", ss_pf, ours_pf, 15)
    line("PF (numpy path) vs Stone Soup", ss_pf, ours_pf_numpy)
    line("PF compiled vs numpy path", ours_pf_numpy, ours_pf)
    print()

    print("RMSE agreement (position RMSE over all epochs; paired difference on common runs)")
    for a, b in pairs:
        d, se, n = paired_rmse_diff(a, b)
        ok = "agree" if abs(d) <= 2 * se or abs(d) < 1e-6 * a.rmse else "DIFFER"
        print(f"  {a.name} - {b.name}: {d:+.3g} m +- {se:.2g} (paired SE, {n} runs)  {ok}")
    print()

    t_pcrlb = time_pcrlb_step(sc, n_mc=1000, n_candidates=9, reps=pcrlb_reps)
    print(
        "PCRLB step (measurement_information + pcrlb_step), 1000 MC samples, 9 candidate "
        f"sensor states: {us(t_pcrlb)}"
    )
    print(f"# benchmark wall time {time.perf_counter() - t_start:.1f} s")
    ekf_part = "" if ekf_speedup is None else f" ekf_speedup_vs_stonesoup={ekf_speedup:.2f}"
    print(f"pf_speedup_vs_stonesoup={pf_speedup:.2f}{ekf_part}")
    return 0


if __name__ == "__main__":
    # As the command line and the nodes do: the timings are those users get.
    tune_allocator()
    sys.exit(main())
