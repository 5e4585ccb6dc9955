"""Reproduce Valverde (USBL range/bearing tracking) Tables I-V and Figs. 2-8.

Two EKFs (eq. 2-9; ``circular``: eq. 24-25; ``constant_turn``, known turn rate: eq. 35-37)
track a vehicle circling a stationary range+bearing sensor (eq. 10-14) for every noise pair of
Table III in two cases: ``crlb`` (no process noise; Taylor's CRLB along the nominal path, eq.
50-51; Table IV) and ``pcrb`` (process noise; the eq. 65 PCRB along the nominal path and, for
constant turn, the Monte Carlo Tichavsky PCRB, eq. 56-64; Tables III and V). Tables I-II are the
rank of the eq. 38 observability matrix. docs/valverde.md explains the cases and the scenario
choices (Fig. 2 is lost).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from functools import partial
from pathlib import Path

import numpy as np

from activetrack.angles import wrap_angle
from activetrack.argtypes import int_in_range
from activetrack.bounds.pcrlb import covariance_bound
from activetrack.bounds.taylor_crlb import nominal_path, taylor_crlb
from activetrack.bounds.tichavsky import tichavsky_pcrlb
from activetrack.checks import require_int, symmetrize
from activetrack.filters import ekf_over_runs
from activetrack.limits import MAX_RUN_EPOCHS, MAX_RUNS, MAX_SEED, MAX_STEPS
from activetrack.models.motion import CircularMotion, ConstantTurn
from activetrack.models.sensors import RangeBearingSensor
from activetrack.montecarlo import Scheduler, TaskProgress, check_jobs, parallel_map
from activetrack.observability import observability_rank
from activetrack.plots import write_figures
from activetrack_experiments.reproduction import Reproduction, RunsOption, figure_axes

MODELS = ("circular", "constant_turn")
NAMES = {"circular": "circular motion", "constant_turn": "constant turn (known rate)"}
CASES = ("crlb", "pcrb")
# Index of (px, py) in each model's state.
POSITION_INDEX = {"circular": (1, 2), "constant_turn": (0, 2)}

# Table III noise pairs: (sigma_r [m], sigma_b [deg]); the paper prints the variances.
NOISE_PAIRS = (
    (0.01, 0.01),
    (0.05, 0.05),
    (0.1, 1.0),
    (1.0, 2.0),
    (3.0, 2.0),
    (4.0, 3.0),
    (4.0, 4.0),
    (5.0, 4.0),
    (5.0, 5.0),
    (5.0, 6.0),
    (6.0, 6.0),
)

# The paper's values as printed, one row per noise pair (Table III equals the MSE columns of
# Table V). Table IV / V: (circ mse x, y, circ bound x, y, ct mse x, y, ct bound x, y).
PAPER_TABLE_IV = (
    (1.177e-3, 9.366e-4, 3.979e-4, 2.927e-4, 1.177e-3, 9.366e-4, 8.897e-4, 6.546e-4),
    (5.886e-3, 4.684e-3, 1.989e-3, 1.464e-3, 5.887e-3, 4.684e-3, 4.448e-3, 3.273e-3),
    (9.224e-2, 6.181e-2, 3.668e-2, 1.731e-2, 9.298e-2, 6.201e-2, 8.196e-2, 3.868e-2),
    (2.175e-1, 1.647e-1, 7.623e-2, 4.393e-2, 2.142e-1, 1.593e-1, 1.700e-1, 9.800e-2),
    (3.557e-1, 4.352e-1, 8.170e-2, 7.185e-2, 2.566e-1, 2.192e-1, 1.822e-1, 1.604e-1),
    (4.859e-1, 5.206e-1, 1.205e-1, 9.895e-2, 3.784e-1, 3.131e-1, 2.680e-1, 2.205e-1),
    (5.590e-1, 5.202e-1, 1.564e-1, 1.120e-1, 4.686e-1, 3.697e-1, 3.460e-1, 2.487e-1),
    (6.630e-1, 6.361e-1, 1.592e-1, 1.259e-1, 4.902e-1, 4.025e-1, 3.524e-1, 2.797e-1),
    (7.520e-1, 6.645e-1, 1.950e-1, 1.391e-1, 5.871e-1, 4.663e-1, 4.290e-1, 3.076e-1),
    (9.956e-1, 8.498e-1, 2.309e-1, 1.534e-1, 6.837e-1, 5.306e-1, 5.041e-1, 3.370e-1),
    (9.272e-1, 8.335e-1, 2.336e-1, 1.661e-1, 7.074e-1, 5.654e-1, 5.102e-1, 3.658e-1),
)
PAPER_TABLE_V = (
    (5.275e-3, 4.102e-3, 3.297e-4, 3.482e-4, 8.059e-2, 6.366e-2, 1.312e-2, 9.592e-3),
    (1.518e-2, 1.345e-2, 1.649e-3, 1.741e-3, 1.865e-1, 1.420e-1, 3.939e-2, 2.908e-2),
    (9.813e-2, 6.894e-2, 6.556e-3, 5.180e-3, 4.033e-1, 3.196e-1, 1.899e-1, 1.070e-1),
    (2.242e-1, 1.727e-1, 4.989e-2, 4.538e-2, 6.084e-1, 5.563e-1, 2.743e-1, 2.042e-1),
    (3.621e-1, 4.414e-1, 7.093e-2, 8.029e-2, 6.643e-1, 6.233e-1, 2.941e-1, 2.765e-1),
    (4.929e-1, 5.273e-1, 1.043e-1, 1.159e-1, 7.388e-1, 6.774e-1, 3.628e-1, 3.301e-1),
    (5.665e-1, 5.280e-1, 1.308e-1, 1.380e-1, 7.921e-1, 7.049e-1, 4.255e-1, 3.571e-1),
    (6.704e-1, 6.435e-1, 1.370e-1, 1.505e-1, 8.098e-1, 7.275e-1, 4.321e-1, 3.827e-1),
    (7.595e-1, 6.721e-1, 1.630e-1, 1.678e-1, 8.761e-1, 7.656e-1, 4.966e-1, 4.104e-1),
    (9.977e-1, 8.526e-1, 1.846e-1, 1.874e-1, 9.458e-1, 8.065e-1, 5.622e-1, 4.390e-1),
    (9.320e-1, 8.383e-1, 1.941e-1, 2.045e-1, 9.673e-1, 8.337e-1, 5.681e-1, 4.636e-1),
)

# Tables IV-V: each case's table number, process noise and the paper's values.
BOUND_TABLES = {
    "crlb": ("IV", "without process noise (eq. 50-51)", PAPER_TABLE_IV),
    "pcrb": ("V", "with process noise (eq. 65, nominal path)", PAPER_TABLE_V),
}

# Tables I-II, eq. 38: the paper's test conditions and ranks (its condition labels are partly
# lost; "omega > v" and "dt -> 0" are from the text). Ours: (label, v, omega, dt, paper ranks).
RANK_CONDITIONS = (
    ("v = 0 (omega = 0.1 rad/s)", 0.0, 0.1, 1.0, (3, 4)),
    ("omega = 0.1 rad/s > v = 0.05 m/s", 0.05, 0.1, 1.0, (4, 4)),
    ("dt = 1e-3 s", 1.0, 0.05, 1e-3, (None, None)),
    ("dt = 1e-6 s", 1.0, 0.05, 1e-6, (None, None)),
    ("dt = 1e-12 s (dt -> 0)", 1.0, 0.05, 1e-12, (4, 2)),
    ("v = 5 m/s, omega = 0", 5.0, 0.0, 1.0, (5, 4)),
)


@dataclass(frozen=True)
class ValverdeSetup:
    """Scenario choices (docs/valverde.md): the vehicle circles ``centre`` counter-clockwise
    from the bottom, heading east. Process noise (pcrb case): sigma_omega [rad/s/sqrt(s)] and
    sigma_v [m/s/sqrt(s)] of eq. 25, q = sigma_v^2 [m^2/s^3] for constant turn. Prior standard
    deviations: heading, position, turn rate, speed."""

    sensor_xy: tuple[float, float] = (0.0, 0.0)
    centre: tuple[float, float] = (30.0, 0.0)
    radius: float = 20.0
    speed: float = 1.0
    dt: float = 1.0
    steps: int = 252  # two laps
    sigma_omega: float = 2e-4
    sigma_v: float = 5e-3
    prior_std: tuple[float, float, float, float] = (0.05, 0.5, 0.005, 0.05)
    noise_pairs: tuple[tuple[float, float], ...] = NOISE_PAIRS

    @property
    def omega(self) -> float:
        return self.speed / self.radius

    @property
    def q(self) -> float:
        return self.sigma_v**2

    @property
    def sensor_pv(self) -> np.ndarray:
        return np.array([self.sensor_xy[0], 0.0, self.sensor_xy[1], 0.0])

    def x0(self, model: str) -> np.ndarray:
        """Nominal initial state of ``model``: bottom of the circle, heading psi = 0."""
        cx, cy = self.centre
        if model == "circular":
            return np.array([0.0, cx, cy - self.radius, self.omega, self.speed])
        return np.array([cx, self.speed, cy - self.radius, 0.0])

    def P0(self, model: str) -> np.ndarray:
        """Prior covariance; for constant_turn the circular prior mapped to pv (omega known)."""
        s_psi, s_p, s_w, s_v = self.prior_std
        P = np.diag([s_psi**2, s_p**2, s_p**2, s_w**2, s_v**2])
        if model == "circular":
            return P
        keep = [0, 1, 2, 4]  # (psi, px, py, v)
        Jk = np.delete(CircularMotion(0.0, 0.0).kinematics_jacobian(self.x0("circular")), 3, 1)
        return symmetrize(Jk @ P[np.ix_(keep, keep)] @ Jk.T)

    def model(self, model: str, process_noise: bool):
        if model == "circular":
            noise = (self.sigma_omega, self.sigma_v) if process_noise else (0.0, 0.0)
            return CircularMotion(*noise)
        return ConstantTurn(self.omega, self.q if process_noise else 0.0)

    @staticmethod
    def sensor(sigma_r: float, sigma_b_deg: float) -> RangeBearingSensor:
        return RangeBearingSensor(sigma_r=sigma_r, sigma_b=np.deg2rad(sigma_b_deg))


@dataclass
class RowResult:
    """One (case, model, noise pair): time-averaged MSE of (px, py) [m^2], its Monte Carlo
    standard error, the time-averaged bound, and the per-epoch series ``(steps, 2)``."""

    case: str
    model: str
    sigma_r: float
    sigma_b_deg: float
    mse: np.ndarray
    se: np.ndarray
    bound: np.ndarray
    mse_t: np.ndarray = field(repr=False)
    bound_t: np.ndarray = field(repr=False)
    bound_mc: np.ndarray | None = None  # Tichavsky Monte Carlo PCRB (constant_turn, pcrb)
    diverged: int = 0

    def to_json(self) -> dict:
        out = {
            "case": self.case,
            "model": self.model,
            "range_variance_m2": self.sigma_r**2,
            "bearing_variance_deg2": self.sigma_b_deg**2,
            "mse_x": float(self.mse[0]),
            "mse_y": float(self.mse[1]),
            "mse_se_x": float(self.se[0]),
            "mse_se_y": float(self.se[1]),
            "rmse_x": float(np.sqrt(self.mse[0])),
            "rmse_y": float(np.sqrt(self.mse[1])),
            "bound_x": float(self.bound[0]),
            "bound_y": float(self.bound[1]),
            "diverged_runs": self.diverged,
        }
        if self.bound_mc is not None:
            out["bound_mc_x"], out["bound_mc_y"] = map(float, self.bound_mc)
        return out

    def row(self) -> dict:
        """:meth:`to_json` with the noise standard deviations and, so that every row has the
        same columns, ``bound_mc_x``/``bound_mc_y`` NaN where there is no Monte Carlo PCRB."""
        out = {"sigma_r_m": self.sigma_r, "sigma_b_deg": self.sigma_b_deg, **self.to_json()}
        out.setdefault("bound_mc_x", math.nan)
        out.setdefault("bound_mc_y", math.nan)
        return out


@dataclass(frozen=True)
class RankRow:
    """One condition of Tables I-II: rank of O (eq. 38) for each model, and the paper's."""

    condition: str
    rank_circular: int
    rank_constant_turn: int
    paper_circular: int | None
    paper_constant_turn: int | None


def _gaussian(mean, P, shape, rng):
    L = np.linalg.cholesky(P)
    return mean + rng.standard_normal((*shape, len(mean))) @ L.T


def simulate_truth(model, x0, P0, steps, dt, runs, rng, random_start):
    """True states for epochs 0..steps, ``(steps + 1, runs, n)``: the nominal path repeated,
    or x_0 ~ N(x0, P0) followed by the model's noisy dynamics (``model.sample``)."""
    if not random_start:
        path = nominal_path(model, x0, steps, dt)
        return np.repeat(path[:, None, :], runs, axis=1)
    X = [_gaussian(x0, P0, (runs,), rng)]
    for _ in range(steps):
        X.append(model.sample(X[-1], dt, rng))
    return np.stack(X)


def measure(sensor, truth_pv, sensor_pv, unit_noise):
    """z = h(x) + (sigma_r, sigma_b) * e with the bearing wrapped; e is shared between noise rows
    (common random numbers make the rows differ by the noise level only)."""
    z = sensor.measure(truth_pv, sensor_pv) + unit_noise * np.sqrt(np.diag(sensor.R))
    z[..., 1] = wrap_angle(z[..., 1])
    return z


def bound_series(setup: ValverdeSetup, model_name: str, sensor, process_noise: bool):
    """Covariance bound ``(steps, n, n)`` along the nominal path: Taylor CRLB (eq. 50-51) or the
    nominal-path PCRB (eq. 65), both with J_0 = P0^{-1}."""
    model = setup.model(model_name, process_noise)
    x0, P0 = setup.x0(model_name), setup.P0(model_name)
    # A candidate axis of size 1 keeps pcrlb_step on numpy's batched solves: its single-matrix
    # LAPACK dtrtrs path takes ~15 ms per call when OpenBLAS runs 2 threads on a busy machine.
    paths = np.broadcast_to(setup.sensor_pv, (setup.steps, 1, 4))
    J = taylor_crlb(
        model, sensor, paths, x0, setup.steps, setup.dt, P0=P0, process_noise=process_noise
    )
    return covariance_bound(J[:, 0])


@dataclass(frozen=True)
class CaseDraws:
    """The random draws of one (case, model), shared by its noise rows (common random numbers):
    true states ``(steps + 1, runs, n)``, prior means ``(runs, n)`` and the unit measurement
    noise ``(steps, runs, 2)``."""

    truth: np.ndarray
    x_hat0: np.ndarray
    unit_noise: np.ndarray


def draw_case(setup: ValverdeSetup, case: str, model_name: str, runs: int, seed: int):
    """The draws of (case, model) from SeedSequence([seed, case index, model index])."""
    process_noise = case == "pcrb"
    model = setup.model(model_name, process_noise)
    x0, P0 = setup.x0(model_name), setup.P0(model_name)
    ss = np.random.SeedSequence([seed, CASES.index(case), MODELS.index(model_name)])
    rng_truth, rng_init, rng_meas = (np.random.default_rng(s) for s in ss.spawn(3))
    truth = simulate_truth(model, x0, P0, setup.steps, setup.dt, runs, rng_truth, process_noise)
    if process_noise:  # the truth is random; the filter starts at the prior mean
        x_hat0 = np.broadcast_to(x0, (runs, model.dim))
    else:  # the truth is fixed; the prior mean is drawn around it (eq. 44)
        x_hat0 = _gaussian(x0, P0, (runs,), rng_init)
    return CaseDraws(truth, x_hat0, rng_meas.standard_normal((setup.steps, runs, 2)))


@dataclass(frozen=True)
class RowTask:
    """One table row for :func:`run_row`: the draws of its (case, model) and its noise pair."""

    setup: ValverdeSetup
    case: str
    model: str
    sigma_r: float
    sigma_b_deg: float
    draws: CaseDraws
    divergence_m: float = 1e3


def _monte_carlo_pcrb(task: RowTask, model, sensor) -> np.ndarray:
    """Time-averaged Tichavsky PCRB of (px, py) over the row's true trajectories (eq. 56-64)."""
    setup, truth = task.setup, task.draws.truth
    paths = np.broadcast_to(setup.sensor_pv, (setup.steps, 4))
    x0, P0, runs = setup.x0(task.model), setup.P0(task.model), truth.shape[1]
    J = tichavsky_pcrlb(
        model, sensor, paths, x0, P0, setup.steps, setup.dt, runs, None, trajectories=truth
    )
    ix = list(POSITION_INDEX[task.model])
    return covariance_bound(J)[:, ix, ix].mean(axis=0)


def run_row(task: RowTask) -> RowResult:
    """The batched EKF's square errors over the row's runs and the bound (a parallel task)."""
    setup, truth = task.setup, task.draws.truth
    process_noise = task.case == "pcrb"
    model = setup.model(task.model, process_noise)
    sensor = setup.sensor(task.sigma_r, task.sigma_b_deg)
    z = measure(sensor, model.kinematics(truth[1:]), setup.sensor_pv, task.draws.unit_noise)
    P0 = setup.P0(task.model)
    means, _ = ekf_over_runs(
        model, sensor, setup.sensor_pv, task.draws.x_hat0, P0, z, setup.dt, keep_cov=False
    )
    ix = list(POSITION_INDEX[task.model])
    err2 = (means[..., ix] - truth[1:, :, ix]) ** 2  # (K, M, 2)
    ok = np.all(np.isfinite(err2) & (err2 < task.divergence_m**2), axis=(0, 2))
    per_run = err2.mean(axis=0)  # time average (K, M, 2) -> (M, 2)
    runs = per_run.shape[0]
    se = per_run.std(axis=0, ddof=1) / np.sqrt(runs) if runs > 1 else np.full(2, np.nan)
    B = bound_series(setup, task.model, sensor, process_noise)[:, ix, ix]
    bound_mc = None
    if process_noise and task.model == "constant_turn":
        bound_mc = _monte_carlo_pcrb(task, model, sensor)
    row, diverged = (task.case, task.model, task.sigma_r, task.sigma_b_deg), int(runs - ok.sum())
    return RowResult(
        *row, per_run.mean(axis=0), se, B.mean(axis=0), err2.mean(axis=1), B, bound_mc, diverged
    )


def observability_table(setup: ValverdeSetup, n_steps: int = 10, rtol: float = 1e-9):
    """Tables I-II (eq. 38): rank of O over ``n_steps`` epochs for each condition and model,
    as a list of :class:`RankRow`."""
    rows = []
    px, py = setup.centre[0], setup.centre[1] - setup.radius
    sensor = setup.sensor(1.0, 1.0)  # the rank does not depend on R
    for label, v, omega, dt, paper in RANK_CONDITIONS:
        models = (
            (CircularMotion(0.0, 0.0), [0.0, px, py, omega, v]),
            (ConstantTurn(omega, 0.0), [px, v, py, 0.0]),
        )
        ranks = [
            observability_rank(m, sensor, np.array(x0), setup.sensor_pv, dt, n_steps, rtol=rtol)
            for m, x0 in models
        ]
        rows.append(RankRow(label, *(r.rank for r in ranks), *paper))
    return rows


@dataclass
class ValverdeResults:
    """What :func:`reproduce` computed: the Monte Carlo rows (``CASES`` x ``MODELS`` x noise
    pairs, in that order) and the observability ranks of Tables I-II."""

    setup: ValverdeSetup
    runs: int
    seed: int
    rows: list[RowResult]
    ranks: list[RankRow]
    mc_time_s: float = 0.0  # the Monte Carlo and the bounds

    def get(self, case: str, model: str) -> list[RowResult]:
        """The rows of (case, model), one per noise pair."""
        if case not in CASES or model not in MODELS:
            raise KeyError(f"no rows for case {case!r}, model {model!r}")
        return [r for r in self.rows if r.case == case and r.model == model]

    def table(self, section: str = "rows") -> list[dict]:
        """A flat dict per Monte Carlo row (``"rows"``, :meth:`RowResult.row`) or per
        condition of Tables I-II (``"observability"``), for ``pandas.DataFrame``."""
        if section == "rows":
            return [r.row() for r in self.rows]
        if section == "observability":
            return [asdict(r) for r in self.ranks]
        raise ValueError(f"section must be 'rows' or 'observability', got {section!r}")

    def to_json(self) -> dict:
        """The document ``--json`` writes."""
        s = self.setup
        setup = {k: v for k, v in asdict(s).items() if k != "noise_pairs"}
        return {
            "setup": {**setup, "omega": s.omega, "q": s.q, "runs": self.runs, "seed": self.seed},
            "observability": [asdict(r) for r in self.ranks],
            "rows": [r.to_json() for r in self.rows],
        }


def reproduce(
    runs: int | None = None,
    *,
    seed: int = 0,
    quick: bool = False,
    jobs: int = 1,
    scheduler: Scheduler | None = None,
    steps: int | None = None,
    setup: ValverdeSetup | None = None,
    noise_pairs: Sequence[tuple[float, float]] | None = None,
    divergence_m: float = 1e3,
    task_progress: Callable[[int, int], None] | None = None,
) -> ValverdeResults:
    """Valverde Tables I-V: ``runs`` Monte Carlo runs (default 1000, 50 when ``quick``) of
    ``steps`` epochs (default 252, two laps; 126 when ``quick``) for every case, model and noise
    pair (default Table III's), and the observability ranks.

    ``setup`` replaces :class:`ValverdeSetup` (its ``steps`` unless ``steps`` is given);
    ``seed``: (case, model) draws from SeedSequence([seed, case, model]), shared by its noise
    rows, which are the tasks of one parallel map; a run counts as diverged when a square error
    exceeds ``divergence_m``^2.
    """
    if steps is None:
        steps = setup.steps if setup is not None else 126 if quick else 252
    runs = (50 if quick else 1000) if runs is None else runs
    require_int("runs", runs, 2, MAX_RUNS)
    require_int("steps", steps, 1, MAX_STEPS)
    if runs * steps > MAX_RUN_EPOCHS:
        raise ValueError(f"runs x steps must be <= {MAX_RUN_EPOCHS:.1e}, got {runs} x {steps}")
    require_int("seed", seed, 0, MAX_SEED)
    check_jobs(jobs, scheduler)
    setup = replace(setup or ValverdeSetup(), steps=steps)
    pairs = tuple(noise_pairs or setup.noise_pairs)
    start = time.perf_counter()
    tasks = []
    for case in CASES:
        for model in MODELS:
            draws = draw_case(setup, case, model, runs, seed)
            tasks += [RowTask(setup, case, model, r, b, draws, divergence_m) for r, b in pairs]
    progress = TaskProgress(len(tasks), task_progress).of_map()
    rows = parallel_map(run_row, tasks, jobs, progress, scheduler)
    mc_time = time.perf_counter() - start
    return ValverdeResults(setup, runs, seed, rows, observability_table(setup), mc_time)


def _noise_label(sr, sb):
    return f"{sr:g}^2".ljust(8) + f"{sb:g}^2".ljust(8)


def _fmt(values):
    return " ".join(f"{v:9.3e}" for v in values)


def format_table_iii(res: ValverdeResults) -> str:
    circ, ct = res.get("pcrb", "circular"), res.get("pcrb", "constant_turn")
    lines = [
        "TABLE III. Square mean error [m^2] of the EKFs (with process noise), ours vs paper",
        "Noise variance   |  Circular motion   | Const. turn, known rate |",
        "d[m^2]  b[deg^2] |  px err    py err  |  px err    py err       |",
    ]
    for i, (a, b) in enumerate(zip(circ, ct, strict=True)):
        lines.append(f"{_noise_label(a.sigma_r, a.sigma_b_deg)} | {_fmt([*a.mse, *b.mse])}")
        paper = PAPER_TABLE_V[i] if i < len(PAPER_TABLE_V) else None
        if paper is not None and (a.sigma_r, a.sigma_b_deg) == NOISE_PAIRS[i]:
            lines.append(f"{'  paper':16} | {_fmt([*paper[0:2], *paper[4:6]])}")
    return "\n".join(lines)


def format_bound_table(res: ValverdeResults, case: str) -> str:
    """Table IV (``case`` "crlb") or V ("pcrb"): MSE and bound of both models, and the paper's."""
    number, noise, paper_table = BOUND_TABLES[case]
    bound_name = case.upper()
    circ, ct = res.get(case, "circular"), res.get(case, "constant_turn")
    lines = [
        f"TABLE {number}. Square mean error [m^2] and {bound_name} {noise}",
        "Noise variance   |        Circular motion state model        |"
        "   Constant turn model with known turn rate  |",
        f"d[m^2]  b[deg^2] |  MSE px    MSE py   {bound_name:>4} px   {bound_name:>4} py  |"
        f"  MSE px    MSE py   {bound_name:>4} px   {bound_name:>4} py  |",
    ]
    for i, (a, b) in enumerate(zip(circ, ct, strict=True)):
        row = _fmt([*a.mse, *a.bound]) + " | " + _fmt([*b.mse, *b.bound])
        lines.append(f"{_noise_label(a.sigma_r, a.sigma_b_deg)} | {row}")
        if i < len(paper_table) and (a.sigma_r, a.sigma_b_deg) == NOISE_PAIRS[i]:
            p = paper_table[i]
            lines.append(f"{'  paper':16} | {_fmt(p[:4])} | {_fmt(p[4:])}")
        if b.bound_mc is not None:
            lines.append(f"{'  ct PCRB (MC)':16} | {'':39} | {'':19} {_fmt(b.bound_mc)}")
    return "\n".join(lines)


def format_rank_tables(rows: list[RankRow]) -> str:
    lines = [
        "TABLES I-II. rank O(k0, kf) (eq. 38), 10 epochs, rtol 1e-9; full rank 5 / 4",
        f"{'Test condition':34} | circular (paper) | const. turn (paper)",
    ]
    for r in rows:
        pc = "-" if r.paper_circular is None else str(r.paper_circular)
        pt = "-" if r.paper_constant_turn is None else str(r.paper_constant_turn)
        lines.append(
            f"{r.condition:34} | {r.rank_circular:>8} ({pc:>4})  | "
            f"{r.rank_constant_turn:>8} ({pt:>4})"
        )
    return "\n".join(lines)


def format_report(res: ValverdeResults) -> str:
    """The header and Tables I-V, as ``activetrack reproduce valverde`` prints them."""
    s = res.setup
    parts = [
        f"Valverde USBL tracking: sensor at {s.sensor_xy}, circle centre {s.centre} m, "
        f"radius {s.radius:g} m, speed {s.speed:g} m/s (omega {s.omega:g} rad/s), "
        f"dt {s.dt:g} s, {s.steps} epochs, {res.runs} runs, seed {res.seed}\n"
        "The paper's numbers scale linearly with the noise std (rows 1-2), i.e. they look like "
        "RMS errors [m]; ours are mean square errors [m^2] (RMS in the JSON).",
        format_rank_tables(res.ranks),
        format_table_iii(res),
        *(format_bound_table(res, case) for case in CASES),
    ]
    return "\n\n".join(parts) + "\n"


def _fig_mse(res: ValverdeResults, case: str, axis: int, num: int):
    """Fig. 3-6: MSE of x or y (2 standard errors) and the bound against the noise pair."""
    labels = [f"{r.sigma_r:g}/{r.sigma_b_deg:g}" for r in res.get("crlb", "circular")]
    idx = np.arange(len(labels))
    fig, ax = figure_axes((7, 4))
    for m, colour in zip(MODELS, ("C0", "C1"), strict=True):
        rows = res.get(case, m)
        mse = np.array([r.mse[axis] for r in rows])
        se = np.array([r.se[axis] for r in rows])
        ax.errorbar(idx, mse, yerr=2 * se, color=colour, marker="o", label=f"EKF {NAMES[m]}")
        bound = [r.bound[axis] for r in rows]
        ax.plot(idx, bound, color=colour, ls="--", label=f"{case.upper()} {NAMES[m]}")
    ax.set_xticks(idx, labels, rotation=45)
    ax.set(yscale="log", xlabel="noise std: range [m] / bearing [deg]")
    ax.set(ylabel=f"{'xy'[axis]} square error [m^2]")
    ax.set_title(f"Fig. {num}: {'xy'[axis]} MSE and {case.upper()} vs noise")
    ax.legend(fontsize=8)
    return fig


def _fig_time(res: ValverdeResults, model: str, num: int, series_row: int):
    """Fig. 7-8: MSE and PCRB against time for one noise pair (with process noise)."""
    row = res.get("pcrb", model)[series_row]
    t = res.setup.dt * np.arange(1, res.setup.steps + 1)
    fig, ax = figure_axes((7, 4))
    for axis, colour in ((0, "C0"), (1, "C3")):
        name = "xy"[axis]
        ax.plot(t, row.mse_t[:, axis], color=colour, alpha=0.4, lw=0.8, label=f"EKF {name} MSE")
        ax.plot(t, row.bound_t[:, axis], color=colour, lw=1.6, label=f"PCRB {name}")
    ax.set(yscale="log", xlabel="time [s]", ylabel="square error [m^2]")
    ax.set_title(
        f"Fig. {num}: {NAMES[model]}, sigma_r = {row.sigma_r:g} m, "
        f"sigma_b = {row.sigma_b_deg:g} deg"
    )
    ax.legend(fontsize=8)
    return fig


def _fig_path(setup: ValverdeSetup):
    """Fig. 2: the nominal path and the USBL."""
    fig, ax = figure_axes((5, 5))
    model = setup.model("circular", False)
    path_xy = nominal_path(model, setup.x0("circular"), setup.steps, setup.dt)[:, 1:3]
    ax.plot(path_xy[:, 0], path_xy[:, 1], label="vehicle (nominal)")
    ax.plot(*setup.sensor_xy, "k^", label="USBL")
    ax.set(aspect="equal", xlabel="x [m]", ylabel="y [m]", title="Fig. 2: test path")
    ax.legend()
    return fig


def save_figures(res: ValverdeResults, out: str | Path, series_row: int = 3) -> list[Path]:
    """Fig. 3-6 (MSE and bound vs noise), 7-8 (against time, noise pair ``series_row``) and
    2 (the path) as PNG files in ``out``; returns the files written."""
    figures = [
        (f"fig{n}_mse_{'xy'[axis]}_{case}.png", partial(_fig_mse, res, case, axis, n))
        for case, axis, n in (("crlb", 0, 3), ("crlb", 1, 4), ("pcrb", 0, 5), ("pcrb", 1, 6))
    ]
    figures += [
        (f"fig{n}_time_{m}.png", partial(_fig_time, res, m, n, series_row))
        for m, n in zip(MODELS, (7, 8), strict=True)
    ]
    figures.append(("fig2_path.png", partial(_fig_path, res.setup)))
    return write_figures(figures, out, dpi=110)


def _options(parser: argparse.ArgumentParser) -> None:
    add = parser.add_argument
    add("--steps", type=int_in_range(1, MAX_STEPS), help="epochs (default 252, two laps)")
    add("--seed", type=int_in_range(0, MAX_SEED), default=0, help="seed of the draws (0)")
    add("--quick", action="store_true", help="50 runs, one lap")
    add("--no-plots", dest="no_figures", action="store_true", help="as --no-figures")


def _check_cli(args: argparse.Namespace) -> None:
    """Sets the runs and epochs (by ``--quick``) and bounds their product."""
    if args.runs is None:
        args.runs = 50 if args.quick else 1000
    if args.steps is None:
        args.steps = 126 if args.quick else 252
    if args.runs * args.steps > MAX_RUN_EPOCHS:
        raise ValueError(
            f"--runs x --steps must be <= {MAX_RUN_EPOCHS:.1e} (the runs are held in memory "
            f"together), got {args.runs} x {args.steps}"
        )


REPRODUCTION = Reproduction(
    "valverde",
    "Valverde USBL tracking: EKF MSE vs CRLB / PCRB (Tables I-V, Figs. 2-8).",
    RunsOption(2, None, "Monte Carlo runs (default 1000)", "the Monte Carlo error needs two runs"),
    options=_options,
    check=_check_cli,
    arguments=lambda args: dict(seed=args.seed, steps=args.steps),
)
main = REPRODUCTION.main


if __name__ == "__main__":
    raise SystemExit(main())
