"""The closed loop without ROS: simulator, tracker and planner in one loop (docs/closed-loop.md).

``run_once`` is the reference the ROS graph reproduces exactly in lockstep mode.
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from activetrack.bounds.pcrlb import (
    covariance_bound,
    gaussian_samples,
    pcrlb_trajectory,
    propagate_samples,
)
from activetrack.closed_loop.data import Decision, TrackSnapshot
from activetrack.closed_loop.planner import PlannerCore
from activetrack.closed_loop.simulator import Simulator
from activetrack.closed_loop.tracker import TrackerCore
from activetrack.filters.registry import filter_kind
from activetrack.kernels import expect_particle_work
from activetrack.models.base import SensorModel, as_linear
from activetrack.montecarlo import Progress, Scheduler, parallel_map
from activetrack.scenarios.build import build_motion_model, build_sensor
from activetrack.scenarios.schema import Scenario

# Monte Carlo samples of the prior for the evaluation bound (Hernandez used 1,000).
BOUND_SAMPLES = 1000


def component_rngs(seed: int, run: int | None = None) -> tuple[np.random.Generator, ...]:
    """(sim, tracker, planner, evaluator) generators: one stream each, fixed by seed and run."""
    ss = np.random.SeedSequence(seed if run is None else [seed, run])
    return tuple(np.random.default_rng(s) for s in ss.spawn(4))


@dataclass
class RunRecord:
    """One closed-loop run: everything at epochs 0..K."""

    truth: np.ndarray  # (K+1, 4) target pv
    estimate: np.ndarray  # (K+1, n) filter mean
    estimate_cov: np.ndarray  # (K+1, n, n)
    platform_paths: np.ndarray  # (K+1, P, 4)
    platform_ids: tuple[str, ...]
    decisions: list[Decision] = field(default_factory=list)
    # (K, S) which sensors looked at epochs 1..K (selection and stop-and-measure gating);
    # None: all of them, every epoch.
    measured: np.ndarray | None = None
    detected: np.ndarray | None = None  # (K, S) and saw the target (batch only)
    missed_detections: int = 0  # the tracker's count at the end of the run
    clamps: int = 0
    wall_time_s: float = 0.0
    planning_time_s: float = 0.0
    evaluations: int = 0


def run_once(scenario: Scenario, run: int | None = None) -> RunRecord:
    """One closed-loop run with the generators of (seed, run)."""
    sim_rng, trk_rng, plan_rng, _ = component_rngs(scenario.seed, run)
    start = time.perf_counter()
    sim = Simulator(scenario, sim_rng)
    tracker = TrackerCore(scenario, trk_rng)
    planner = PlannerCore(scenario, plan_rng)
    ids = tuple(sim.platforms)
    track = tracker.snapshot()
    truth: list[np.ndarray] = []
    est: list[np.ndarray] = []
    est_cov: list[np.ndarray] = []
    paths: list[np.ndarray] = []
    decisions: list[Decision] = []
    clamps = 0
    evaluations = 0
    planning = 0.0

    def record(track: TrackSnapshot) -> None:
        truth.append(sim.truth_pv())
        est.append(track.mean)
        est_cov.append(track.cov)
        paths.append(np.stack([sim.platforms[i].pv for i in ids]))

    record(track)
    sensor_ids = list(sim.sensors)
    measured: list[list[bool]] = []
    detected: list[list[bool]] = []
    for k in range(scenario.steps + 1):
        if k > 0:
            measurements = sim.advance()
            looked = {m.sensor_id for m in measurements}
            seen = {m.sensor_id for m in measurements if m.z is not None}
            measured.append([sid in looked for sid in sensor_ids])
            detected.append([sid in seen for sid in sensor_ids])
            track = tracker.step(k, sim.time, measurements)
            record(track)
        if k < scenario.steps:
            decision = planner.decide(k, track, sim.platform_snapshots())
            decisions.append(decision)
            if decision.report is not None:
                evaluations += decision.report.evaluations
                planning += decision.report.wall_time_s
            for cmd in decision.commands:
                clamps += sim.apply_command(cmd).clamped
            if decision.selected_sensor_ids is not None:
                sim.apply_selection(decision.selected_sensor_ids)
    return RunRecord(
        truth=np.array(truth),
        estimate=np.array(est),
        estimate_cov=np.array(est_cov),
        platform_paths=np.array(paths),
        platform_ids=ids,
        decisions=decisions,
        measured=np.array(measured, dtype=bool).reshape(-1, len(sensor_ids)),
        detected=np.array(detected, dtype=bool).reshape(-1, len(sensor_ids)),
        missed_detections=track.missed_detections,
        clamps=clamps,
        wall_time_s=time.perf_counter() - start,
        planning_time_s=planning,
        evaluations=evaluations,
    )


def path_bound(scenario: Scenario, record: RunRecord, rng: np.random.Generator) -> np.ndarray:
    """PCRLB (Hernandez eq. 3, 8-9) along the flown platform paths: (K, 4, 4) bound J^-1.

    Only the sensors that looked at an epoch (``record.measured``) contribute to its J_Z.
    Linear (NCV) target dynamics only; NaN for other motion models.
    """
    model = build_motion_model(scenario.target.motion)
    K = scenario.steps
    if not model.is_linear:
        return np.full((K, 4, 4), math.nan)
    linear = as_linear(model)
    prior = scenario.target.prior
    C0 = prior.covariance()
    sensors: list[SensorModel] = []
    columns: list[int] = []
    for j, p in enumerate(scenario.platforms):
        for s in p.sensors:
            sensors.append(build_sensor(s))
            columns.append(j)
    paths = record.platform_paths[1:, columns, :]  # (K, S, 4)
    F, Q = linear.transition_matrix(scenario.dt), linear.process_noise(scenario.dt)
    X0 = gaussian_samples(np.array(prior.mean), C0, BOUND_SAMPLES, rng)
    J = pcrlb_trajectory(np.linalg.inv(C0), F, Q, X0, sensors, paths, rng, active=record.measured)
    return covariance_bound(J)


class PathBound:
    """:func:`path_bound` one epoch at a time, for a run in progress (the live view's bound):
    the same recursion (Hernandez eq. 3, 8-9) drawing the same samples from ``rng`` in the same
    order, so step k gives the summary's bound of epoch k (tested to 1e-12). NaN for nonlinear
    target motion, as there."""

    def __init__(self, scenario: Scenario, rng: np.random.Generator):
        model = build_motion_model(scenario.target.motion)
        self.linear = model.is_linear
        self.sensors: list[SensorModel] = []
        self.columns: list[int] = []
        if not self.linear:
            return
        linear = as_linear(model)
        prior = scenario.target.prior
        C0 = prior.covariance()
        for j, p in enumerate(scenario.platforms):
            for s in p.sensors:
                self.sensors.append(build_sensor(s))
                self.columns.append(j)
        self.F, self.Q = linear.transition_matrix(scenario.dt), linear.process_noise(scenario.dt)
        self.rng = rng
        self.samples = gaussian_samples(np.array(prior.mean), C0, BOUND_SAMPLES, rng)
        self.J = np.linalg.inv(C0)

    def step(self, platform_pv: np.ndarray, measured: np.ndarray) -> np.ndarray:
        """The bound J^-1 ``(4, 4)`` at the next epoch, from the platforms' pv ``(P, 4)`` at
        that epoch and which sensors measured there ``(S,)`` (scenario order)."""
        if not self.linear:
            return np.full((4, 4), math.nan)
        self.samples = propagate_samples(self.samples, self.F, self.Q, 1, self.rng)[0]
        paths = np.asarray(platform_pv)[self.columns][None]
        J = pcrlb_trajectory(
            self.J,
            self.F,
            self.Q,
            self.samples[None],
            self.sensors,
            paths,
            active=np.asarray(measured)[None],
        )
        self.J = J[0]
        return covariance_bound(self.J)


@dataclass
class BatchSummary:
    scenario: str
    runs: int
    steps: int
    rmse_x: float
    rmse_y: float
    mean_bound_x: float
    mean_bound_y: float
    rmse_x_t: list[float]
    rmse_y_t: list[float]
    bound_x_t: list[float]
    bound_y_t: list[float]
    clamps: int
    evaluations_per_decision: float
    decision_time_s: float
    wall_time_s: float
    dt: float = 1.0
    records: list[RunRecord] = field(default_factory=list, repr=False)
    # (R, K, 4) target pv at epochs 1..K of each run: truth and the estimate's kinematics.
    truth_pv: np.ndarray = field(default_factory=lambda: np.empty((0, 0, 4)), repr=False)
    estimate_pv: np.ndarray = field(default_factory=lambda: np.empty((0, 0, 4)), repr=False)

    def to_json(self) -> dict:
        arrays = ("records", "truth_pv", "estimate_pv")
        d = {k: v for k, v in self.__dict__.items() if k not in arrays}
        return d

    @property
    def time(self) -> np.ndarray:
        """Epoch times t_1..t_K (K,) [s] of the per-epoch series."""
        return self.dt * np.arange(1, self.steps + 1)

    @property
    def rmse_t(self) -> np.ndarray:
        """RMSE over runs per epoch, (K, 2) [m] in x and y."""
        return np.column_stack([self.rmse_x_t, self.rmse_y_t])

    @property
    def bound_t(self) -> np.ndarray:
        """The PCRLB along the flown paths per epoch, (K, 2) [m] in x and y."""
        return np.column_stack([self.bound_x_t, self.bound_y_t])

    def table(self) -> list[dict[str, float | int | str]]:
        """A tidy table: one row per epoch (``pandas.DataFrame(s.table())``, or csv)."""
        rows: list[dict[str, float | int | str]] = []
        for k in range(self.steps):
            rows.append(
                {
                    "scenario": self.scenario,
                    "epoch": k + 1,
                    "time_s": float(self.time[k]),
                    "rmse_x_m": self.rmse_x_t[k],
                    "rmse_y_m": self.rmse_y_t[k],
                    "bound_x_m": self.bound_x_t[k],
                    "bound_y_m": self.bound_y_t[k],
                }
            )
        return rows

    def run_table(self) -> list[dict[str, float | int | str]]:
        """A tidy table of the runs: one row per run and epoch 1..K, with the target's true and
        estimated position (the filter's state mapped to position/velocity by its model)."""
        rows: list[dict[str, float | int | str]] = []
        for r in range(self.runs):
            truth, est = self.truth_pv[r], self.estimate_pv[r]
            for k in range(self.steps):
                rows.append(
                    {
                        "scenario": self.scenario,
                        "run": r,
                        "epoch": k + 1,
                        "time_s": float(self.time[k]),
                        "x_m": float(truth[k, 0]),
                        "y_m": float(truth[k, 2]),
                        "x_hat_m": float(est[k, 0]),
                        "y_hat_m": float(est[k, 2]),
                    }
                )
        return rows

    def to_csv(self, path: str | Path, runs: bool = False) -> Path:
        """Write :meth:`table` (or :meth:`run_table` with ``runs=True``) as csv."""
        rows = self.run_table() if runs else self.table()
        path = Path(path)
        with path.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        return path


def _run_task(task: tuple[Scenario, int | None]) -> tuple[RunRecord, np.ndarray]:
    """One run and its bound along the flown paths (the evaluator generator of the run), both
    on the worker: the parent only adds up."""
    scenario, run = task
    record = run_once(scenario, run)
    return record, path_bound(scenario, record, component_rngs(scenario.seed, run)[3])


def run_batch(
    scenario: Scenario,
    runs: int = 1,
    jobs: int = 1,
    progress: Progress | None = None,
    scheduler: Scheduler | None = None,
) -> BatchSummary:
    """``runs`` seeded closed-loop runs on ``jobs`` worker processes, or on the workers of the
    Dask cluster ``scheduler`` (``tcp://host:port`` or a ``distributed.Client``), summarised
    by :func:`summarize`. Run r draws from its own generators (:func:`component_rngs`), so the
    result is the same for every ``jobs`` and backend. ``progress(done)`` is called as runs
    finish (:func:`activetrack.montecarlo.parallel_map`); it does not change the result."""
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ValueError(f"runs: must be an integer >= 1, got {runs!r}")
    start = time.perf_counter()
    tasks = [(scenario, r if runs > 1 else None) for r in range(runs)]
    if filter_kind(scenario.tracker.filter).particle_based:  # kernels loaded before the fork
        expect_particle_work(runs * scenario.steps * scenario.tracker.particles)
    results = parallel_map(_run_task, tasks, jobs, progress, scheduler)
    records = [record for record, _ in results]
    bounds = np.stack([bound for _, bound in results])
    return summarize(scenario, records, time.perf_counter() - start, bounds)


def summarize(
    scenario: Scenario,
    records: list[RunRecord],
    wall_time_s: float,
    bounds: np.ndarray | None = None,
) -> BatchSummary:
    """RMSE vs truth and the PCRLB along the flown paths over one or more runs.

    RMSE at epoch k is the root mean square over runs; the reported figure is its arithmetic
    mean over k = 1..K (as Hernandez' Table 1). The bound is averaged the same way: ``bounds``
    (R, K, 4, 4), each run's :func:`path_bound` with its evaluator generator, computed here
    unless given (``run_batch`` computes them on the workers).
    """
    runs = len(records)
    est = np.stack([r.estimate[1:] for r in records])  # (R, K, n)
    truth = np.stack([r.truth[1:] for r in records])  # (R, K, 4)
    model = build_motion_model(scenario.tracker.motion or scenario.target.motion)
    est_pv = model.kinematics(est)
    sq = (est_pv - truth) ** 2
    rmse_x_t = np.sqrt(sq[..., 0].mean(axis=0))
    rmse_y_t = np.sqrt(sq[..., 2].mean(axis=0))
    B = bounds
    if B is None:
        B = np.stack(
            [
                path_bound(
                    scenario, rec, component_rngs(scenario.seed, None if runs == 1 else r)[3]
                )
                for r, rec in enumerate(records)
            ]
        )  # (R, K, 4, 4)
    bound_x_t = np.sqrt(B[..., 0, 0].mean(axis=0))
    bound_y_t = np.sqrt(B[..., 2, 2].mean(axis=0))
    decisions = sum(len(r.decisions) for r in records)
    return BatchSummary(
        scenario=scenario.name,
        runs=runs,
        steps=scenario.steps,
        rmse_x=float(rmse_x_t.mean()),
        rmse_y=float(rmse_y_t.mean()),
        mean_bound_x=float(bound_x_t.mean()),
        mean_bound_y=float(bound_y_t.mean()),
        rmse_x_t=rmse_x_t.tolist(),
        rmse_y_t=rmse_y_t.tolist(),
        bound_x_t=bound_x_t.tolist(),
        bound_y_t=bound_y_t.tolist(),
        clamps=sum(r.clamps for r in records),
        evaluations_per_decision=sum(r.evaluations for r in records) / max(decisions, 1),
        decision_time_s=sum(r.planning_time_s for r in records) / max(decisions, 1),
        wall_time_s=wall_time_s,
        dt=scenario.dt,
        records=records,
        truth_pv=truth,
        estimate_pv=est_pv,
    )
