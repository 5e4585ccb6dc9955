"""Reproduce Hernandez (Fusion 2004) Tables 1-2 and Figs. 2-3 (``activetrack reproduce hernandez``).

For 1, 2 and 3 sensors and single-step (eq. 11) / two-step (eq. 13-15) planning on the sec. 5.1
scenario: plan the sensor paths open loop from the prior (sec. 3.2), average the PCRLB RMSE
bounds sqrt(J_k^-1(1,1)), sqrt(J_k^-1(3,3)) over k = 1..30, then track the target along the
planned paths with a 10,000-particle SIR filter (sec. 5.2) over seeded Monte Carlo runs and
average the filter RMSEs the same way. Also compares the quadrant search with the 101 x 101
grid on the 1-sensor single-step case (sec. 4.2, Fig. 2). See docs/hernandez.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from activetrack import limits
from activetrack.argtypes import int_in_range
from activetrack.bounds.pcrlb import (
    covariance_bound,
    gaussian_samples,
    pcrlb_step,
    propagate_samples,
)
from activetrack.filters import Measurement, ParticleFilter
from activetrack.geometry import covariance_ellipse
from activetrack.kernels import expect_particle_work
from activetrack.montecarlo import Progress, Scheduler, TaskProgress, check_jobs, parallel_map
from activetrack.montecarlo.dask import connected
from activetrack.planning import PlannerPlatform, TargetBelief, plan, platform_information
from activetrack.plots import write_figures
from activetrack.scenarios import Scenario, build_motion_model, load_scenario
from activetrack.scenarios.build import plan_settings, planner_platforms
from activetrack.scenarios.schema import PlannerConfig
from activetrack_experiments.paths import find_scenarios_dir, scenario_path
from activetrack_experiments.reproduction import Reproduction, RunsOption, figure_axes, map_groups

# Hernandez Table 1: (sensors, horizon) -> (bound_x, bound_y, pf_rmse_x, pf_rmse_y), metres.
PAPER_TABLE1 = {
    (1, 1): (12.3, 13.9, 13.9, 18.1),
    (1, 2): (11.9, 10.1, 13.2, 10.7),
    (2, 1): (7.1, 7.3, 7.6, 9.1),
    (2, 2): (6.8, 6.7, 7.5, 7.1),
    (3, 1): (5.9, 6.0, 6.9, 6.8),
    (3, 2): (5.0, 5.1, 6.1, 7.0),
}
# Table 2: sensors -> (% bound x, % bound y, % pf x, % pf y) improvement of two-step.
PAPER_TABLE2 = {
    1: (3.6, 27.6, 4.5, 40.6),
    2: (5.5, 8.1, 2.0, 21.7),
    3: (15.1, 15.2, 11.1, -2.6),
}
HORIZON_NAMES = {1: "single", 2: "two"}
SENSOR_COUNTS = (1, 2, 3)
HORIZONS = (1, 2)
SEARCHES = ("quadrant", "grid", "sector")
TABLE2_KEYS = ("bound_x", "bound_y", "pf_rmse_x", "pf_rmse_y")
FIGURE_SAMPLES = 1000  # prior samples drawn for Fig. 2(a)


def scenario_name(sensors: int, horizon: int) -> str:
    """The scenario file stem of a case: ``hernandez_2sensor_two``."""
    return f"hernandez_{sensors}sensor_{HORIZON_NAMES[horizon]}"


@dataclass
class PlannedCase:
    """Open-loop plan of one case: paths (K+1, P, 4), bounds (K, 2), bound covariances."""

    sensors: int
    horizon: int
    search: str
    platform_ids: list
    paths: np.ndarray
    bounds: np.ndarray
    P: np.ndarray
    target_mean: np.ndarray
    evaluations: list = field(default_factory=list)
    decision_times: list = field(default_factory=list)
    iterations: list = field(default_factory=list)


def _next_platforms(platforms: list[PlannerPlatform], result) -> list[PlannerPlatform]:
    """The platforms after flying the leg of their planned manoeuvres."""
    out = []
    for p in platforms:
        m = result.manoeuvre(p.platform_id)
        out.append(
            PlannerPlatform(
                p.platform_id, m.next_pv, p.sensors, p.limits, heading=m.heading, speed=m.speed
            )
        )
    return out


def plan_case(
    scenario: Scenario,
    *,
    search: str | None = None,
    grid_size: int | None = None,
    mc_samples: int | None = None,
    seed: int | None = None,
) -> PlannedCase:
    """Plan the sensor paths open loop from the prior (Hernandez sec. 3.2) and record the PCRLB
    along them: J_{k+1} by eq. 3 with J_Z (eq. 8-9) over the prior samples at k+1."""
    model = build_motion_model(scenario.target.motion)
    dt, K = scenario.dt, scenario.steps
    F, Q = model.transition_matrix(dt), model.process_noise(dt)
    overrides = {k: v for k, v in (("search", search), ("grid_size", grid_size)) if v is not None}
    settings = plan_settings(scenario.planner, **overrides)
    rng = np.random.default_rng(scenario.seed if seed is None else seed)
    M = scenario.planner.mc_samples if mc_samples is None else mc_samples
    prior = scenario.target.prior
    C0 = prior.covariance()
    X0 = gaussian_samples(np.asarray(prior.mean), C0, M, rng)
    samples = propagate_samples(X0, F, Q, K, rng)  # prior samples at k = 1..K (sec. 3.2)
    platforms = planner_platforms(scenario)
    ids = [p.platform_id for p in platforms]
    case = PlannedCase(len(platforms), settings.horizon, settings.search.search, ids, *[None] * 4)
    J = covariance_bound(C0)  # eq. 4: J_0 = C_0^{-1}
    X = X0
    paths = [np.stack([p.pv for p in platforms])]
    bounds, Ps = [], []
    for k in range(K):
        # The planner looks ahead noise-free from the prior samples at k (l = 1e-8 here).
        result = plan(platforms, TargetBelief(J, X), settings, F=F, Q=Q, dt=dt)
        case.evaluations.append(result.report.evaluations)
        case.decision_times.append(result.report.wall_time_s)
        case.iterations.append(result.report.iterations)
        platforms = _next_platforms(platforms, result)
        X = samples[k]
        J_Z = sum(platform_information(p.sensors, p.pv, X) for p in platforms)
        J = pcrlb_step(J, F, Q, J_Z)
        P = covariance_bound(J)
        Ps.append(P)
        bounds.append([np.sqrt(P[0, 0]), np.sqrt(P[2, 2])])
        paths.append(np.stack([p.pv for p in platforms]))
    case.paths = np.stack(paths)
    case.bounds = np.array(bounds)
    case.P = np.stack(Ps)
    mean0 = np.asarray(prior.mean, dtype=float)
    case.target_mean = np.stack([np.linalg.matrix_power(F, k) @ mean0 for k in range(K + 1)])
    return case


@dataclass(frozen=True)
class _RunTask:
    """One Monte Carlo PF run along fixed paths; carries its own run id and seed."""

    scenario: Scenario
    paths: np.ndarray
    run: int
    particles: int
    seed: int


def _track_run(task: _RunTask) -> np.ndarray:
    """Squared PF errors (K, 4) of run ``task.run``: truth/measurements and filter draw from
    the two generators of ``SeedSequence([seed, run])``.

    The core Simulator is not used: its ``detect`` draws a Bernoulli(pd) even at pd = 1 and it
    flies its own legs instead of the fixed planned paths, so the numbers would change.
    """
    scenario, paths = task.scenario, task.paths
    model = build_motion_model(scenario.target.motion)
    dt, K = scenario.dt, scenario.steps
    platforms = planner_platforms(scenario)
    prior = scenario.target.prior
    mean0, C0 = np.asarray(prior.mean, dtype=float), prior.covariance()
    sim_rng, pf_rng = (
        np.random.default_rng(s) for s in np.random.SeedSequence([task.seed, task.run]).spawn(2)
    )
    truth = mean0 + np.linalg.cholesky(C0) @ sim_rng.standard_normal(4)
    pf = ParticleFilter(model, mean0, C0, n_particles=task.particles, rng=pf_rng)
    out = np.empty((K, 4))
    for k in range(1, K + 1):
        truth = model.sample(truth, dt, sim_rng)
        ms = []
        for i, p in enumerate(platforms):
            s_pv = paths[k, i]
            for sensor in p.sensors:
                # No measurement inside the minimum detection range (sec. 2.3).
                inside = sensor.in_range(truth, s_pv)
                z = sensor.sample(truth, s_pv, sim_rng) if inside else None
                ms.append(Measurement(sensor, s_pv, z, k * dt))
        pf.step(k * dt, ms)
        out[k - 1] = (pf.mean - truth) ** 2
    return out


def track_case(
    scenario: Scenario,
    paths: np.ndarray,
    runs: int,
    particles: int,
    seed: int,
    jobs: int = 1,
    progress: Progress | None = None,
    scheduler: Scheduler | None = None,
) -> np.ndarray:
    """PF RMSE per epoch (K, 2) in x and y over ``runs`` seeded runs (run r: SeedSequence
    ([seed, r]) split into truth/measurement and filter generators)."""
    tasks = [_RunTask(scenario, paths, r, particles, seed) for r in range(runs)]
    expect_particle_work(runs * scenario.steps * particles)  # kernels loaded before the fork
    return _rmse(parallel_map(_track_run, tasks, jobs, progress, scheduler))


def _rmse(squared_errors: Sequence[np.ndarray]) -> np.ndarray:
    """RMSE per epoch (K, 2) in x and y from the runs' squared errors, each (K, 4)."""
    mse = np.stack(squared_errors).mean(axis=0)
    return np.sqrt(mse[:, [0, 2]])


def prior_samples(scenario: Scenario, count: int = FIGURE_SAMPLES) -> np.ndarray:
    """Samples of the target prior at k = 0..K (K+1, count, 4), scenario seed (Fig. 2a)."""
    model = build_motion_model(scenario.target.motion)
    rng = np.random.default_rng(scenario.seed)
    prior = scenario.target.prior
    X0 = gaussian_samples(np.asarray(prior.mean), prior.covariance(), count, rng)
    F, Q = model.transition_matrix(scenario.dt), model.process_noise(scenario.dt)
    return np.concatenate([X0[None], propagate_samples(X0, F, Q, scenario.steps, rng)])


def _mean(values) -> float:
    return float(np.mean(values))


@dataclass
class CaseResult:
    """One case of Table 1: the open-loop plan with its bounds and (runs > 0) PF RMSEs."""

    plan: PlannedCase
    planning_time_s: float
    rmse: np.ndarray | None = None  # (K, 2) PF RMSE per epoch, x and y
    runs: int = 0
    particles: int = 0
    tracking_time_s: float | None = None

    @property
    def key(self) -> tuple[int, int]:
        return (self.plan.sensors, self.plan.horizon)

    # Time averages over k = 1..K of the bounds and (runs > 0) the PF RMSEs, m.
    bound_x = property(lambda self: float(self.plan.bounds[:, 0].mean()))
    bound_y = property(lambda self: float(self.plan.bounds[:, 1].mean()))
    pf_rmse_x = property(lambda self: None if self.rmse is None else float(self.rmse[:, 0].mean()))
    pf_rmse_y = property(lambda self: None if self.rmse is None else float(self.rmse[:, 1].mean()))

    def summary(self) -> dict:
        """The case's scalar numbers (a row of ``HernandezResults.table()``)."""
        paper = PAPER_TABLE1[self.key]
        return {
            "sensors": self.plan.sensors,
            "horizon": self.plan.horizon,
            "search": self.plan.search,
            **{key: getattr(self, key) for key in TABLE2_KEYS},
            "evaluations_per_decision": _mean(self.plan.evaluations),
            "decision_time_s": _mean(self.plan.decision_times),
            "sensor_iterations_per_decision": _mean(self.plan.iterations),
            "planning_time_s": self.planning_time_s,
            **{f"paper_{key}": v for key, v in zip(TABLE2_KEYS, paper, strict=True)},
        }

    def to_json(self) -> dict:
        """The case's entry of the JSON document."""
        plan_ = self.plan
        doc = self.summary()
        doc["bound_x_by_epoch"] = plan_.bounds[:, 0].tolist()
        doc["bound_y_by_epoch"] = plan_.bounds[:, 1].tolist()
        doc["sensor_paths"] = {
            pid: plan_.paths[:, i].tolist() for i, pid in enumerate(plan_.platform_ids)
        }
        if self.rmse is not None:
            doc.update(
                pf_rmse_x_by_epoch=self.rmse[:, 0].tolist(),
                pf_rmse_y_by_epoch=self.rmse[:, 1].tolist(),
                pf_runs=self.runs,
                pf_particles=self.particles,
                tracking_time_s=self.tracking_time_s,
            )
        return doc


def _search_summary(case: PlannedCase) -> dict:
    return {
        "bound_x": float(case.bounds[:, 0].mean()),
        "bound_y": float(case.bounds[:, 1].mean()),
        "mean_b_k": float(case.bounds.max(axis=1).mean()),
        "evaluations_per_decision": _mean(case.evaluations),
        "decision_time_s": _mean(case.decision_times),
    }


@dataclass
class SearchComparison:
    """Quadrant search vs the grid on the 1-sensor single-step case (sec. 4.2, Fig. 2)."""

    grid_size: int
    quadrant: PlannedCase
    grid: PlannedCase

    @property
    def separation(self) -> np.ndarray:
        """Distance (K+1,) between the quadrant and the grid sensor positions, m."""
        diff = self.quadrant.paths[:, 0, [0, 2]] - self.grid.paths[:, 0, [0, 2]]
        return np.linalg.norm(diff, axis=1)

    def to_json(self) -> dict:
        gap = self.separation
        return {
            "sensors": 1,
            "horizon": 1,
            "grid_size": self.grid_size,
            "quadrant": _search_summary(self.quadrant),
            "grid": _search_summary(self.grid),
            "path_separation_m": {"max": float(gap.max()), "final": float(gap[-1])},
            "grid_path": self.grid.paths[:, 0].tolist(),
            "quadrant_path": self.quadrant.paths[:, 0].tolist(),
        }


@dataclass
class HernandezResults:
    """Everything ``reproduce`` computed: the cases (sorted by sensors, horizon), the search
    comparison, and what the figures need (epoch times, prior samples for Fig. 2a)."""

    runs: int
    particles: int
    cases: list[CaseResult]
    comparison: SearchComparison | None
    times: np.ndarray  # (K,) epoch times k = 1..K, s
    prior_samples: np.ndarray | None = None  # (K+1, 1000, 4), with the comparison only

    def case(self, sensors: int, horizon: int) -> CaseResult | None:
        return next((c for c in self.cases if c.key == (sensors, horizon)), None)

    def improvements(self) -> dict[int, list[float | None]]:
        """Table 2: % improvement of two-step over single-step per sensor count."""
        out = {}
        for n in SENSOR_COUNTS:
            s, t = self.case(n, 1), self.case(n, 2)
            if s is not None and t is not None:
                pairs = [(getattr(s, key), getattr(t, key)) for key in TABLE2_KEYS]
                out[n] = [None if a is None or b is None else 100 * (a - b) / a for a, b in pairs]
        return out

    def to_json(self) -> dict:
        """The JSON document of ``activetrack reproduce hernandez --json`` (without the list
        of figure files the command line adds)."""
        return {
            "experiment": "hernandez2004",
            "units": {"bounds": "m", "time": "s"},
            "runs": self.runs,
            "particles": self.particles,
            "cases": [c.to_json() for c in self.cases],
            "table2_improvement_percent": {
                str(n): dict(zip(TABLE2_KEYS, v, strict=True))
                for n, v in self.improvements().items()
            },
            "search_comparison": None if self.comparison is None else self.comparison.to_json(),
        }

    def table(self) -> list[dict]:
        """Table 1 as a tidy table: one flat dict per case (with the paper's numbers and the
        PF settings); ``pandas.DataFrame(res.table())``."""
        rows = []
        for c in self.cases:
            row = c.summary()
            row.update(pf_runs=c.runs, pf_particles=c.particles, tracking_time_s=c.tracking_time_s)
            rows.append(row)
        return rows


def _sorted_choice(values: Iterable[int], allowed: tuple[int, ...], option: str) -> list[int]:
    try:
        out = sorted({int(v) for v in values})
    except (TypeError, ValueError):
        raise ValueError("--sensors and --horizons take comma-separated integers") from None
    if not out or not set(out) <= set(allowed):
        raise ValueError(f"{option} must be among {','.join(map(str, allowed))}")
    return out


def check_options(
    *,
    sensors: Iterable[int] = SENSOR_COUNTS,
    horizons: Iterable[int] = HORIZONS,
    search: str | None = None,
    grid_size: int = 101,
    mc_samples: int | None = None,
    comparison: bool = True,
) -> tuple[list[int], list[int]]:
    """The sorted sensor counts and horizons, or a ValueError naming the option at fault
    (unknown counts, or a search too costly for the memory and time limits)."""
    counts = _sorted_choice(sensors, SENSOR_COUNTS, "--sensors")
    horizon_list = _sorted_choice(horizons, HORIZONS, "--horizons")
    if search is not None and search not in SEARCHES:
        raise ValueError(f"--search must be one of {', '.join(SEARCHES)}, got {search!r}")
    # --search grid plans on the scenarios' grid (101 x 101): two steps nest two grids.
    if search == "grid" and 2 in horizon_list:
        per_decision = PlannerConfig().grid_size ** 4
        if per_decision > limits.MAX_SEARCH_EVALUATIONS:
            raise ValueError(
                f"--search grid with --horizons 2 costs {per_decision:.2e} cost evaluations per "
                f"decision, at most {limits.MAX_SEARCH_EVALUATIONS:.0e}: use --horizons 1"
            )
    # The grid comparison scores up to 2,048 grid points against every planner sample at once.
    samples = 1000 if mc_samples is None else mc_samples
    batch = min(grid_size**2, 2048) * samples
    if comparison and 1 in counts and batch > limits.MAX_PLANNER_BATCH:
        raise ValueError(
            f"--mc-samples {samples} with --grid-size {grid_size} scores {batch:.2e} "
            f"sample-candidate pairs at once, at most {limits.MAX_PLANNER_BATCH:.1e} (about 1 GB)"
        )
    return counts, horizon_list


def _plan_task(task: tuple[Scenario, dict]) -> CaseResult:
    """One case's plan and planning time (a task of the plan map)."""
    scenario, plan_kw = task
    t0 = time.perf_counter()
    case = plan_case(scenario, **plan_kw)
    return CaseResult(case, time.perf_counter() - t0)


def _timed_track_run(task: _RunTask) -> tuple[np.ndarray, float]:
    """:func:`_track_run` and its wall time in the worker."""
    t0 = time.perf_counter()
    return _track_run(task), time.perf_counter() - t0


def _plan_order(task: tuple[Scenario, dict]) -> tuple[int, int]:
    """Sort key of the plan map, heaviest first: two-step before single-step (about 4x the
    decision time), then more sensors first; the grid search (10,201 candidates) counts as a
    two-step case of one sensor."""
    scenario, kw = task
    sensors = len(planner_platforms(scenario))
    horizon = 2 if kw.get("search") == "grid" else scenario.planner.horizon
    return (-horizon, -sensors)


def _plan_all(
    plan_tasks: list[tuple[Scenario, dict]],
    jobs: int,
    tasks: TaskProgress,
    scheduler: Scheduler | None,
) -> list[CaseResult]:
    """:func:`_plan_task` of every task in one map, heaviest first so that no long plan starts
    last on an otherwise idle pool; results in the tasks' order."""
    order = sorted(range(len(plan_tasks)), key=lambda i: _plan_order(plan_tasks[i]))
    done = parallel_map(_plan_task, [plan_tasks[i] for i in order], jobs, tasks.of_map(), scheduler)
    return [done[order.index(i)] for i in range(len(order))]


def _plan_and_track(
    scenarios: list[Scenario],
    *,
    runs: int,
    particles: int,
    seed: int | None,
    jobs: int,
    tasks: TaskProgress,
    scheduler: Scheduler | None = None,
    extra_plans: Sequence[tuple[Scenario, dict]] = (),
    **plan_kw,
) -> tuple[list[CaseResult], list[CaseResult]]:
    """Every case planned, with ``extra_plans`` (``(scenario, plan_case keywords)``), in one
    map, then all cases' ``runs`` PF runs along their paths in another; each task carries its
    seeds. A case's ``tracking_time_s`` sums its runs' times. Returns the cases and extra plans."""
    seeds = [sc.seed if seed is None else seed for sc in scenarios]
    plan_tasks = [(sc, {**plan_kw, "seed": sd}) for sc, sd in zip(scenarios, seeds, strict=True)]
    planned = _plan_all(plan_tasks + list(extra_plans), jobs, tasks, scheduler)
    results, extra = planned[: len(scenarios)], planned[len(scenarios) :]
    if runs == 0:
        return results, extra
    run_tasks = [
        [_RunTask(sc, res.plan.paths, r, particles, sd) for r in range(runs)]
        for sc, res, sd in zip(scenarios, results, seeds, strict=True)
    ]
    expect_particle_work(len(scenarios) * runs * scenarios[0].steps * particles)  # before fork
    parts = map_groups(_timed_track_run, run_tasks, jobs, tasks.of_map(), scheduler)
    for res, part in zip(results, parts, strict=True):
        res.rmse = _rmse([sq for sq, _ in part])
        res.runs, res.particles = runs, particles
        res.tracking_time_s = sum(t for _, t in part)
    return results, extra


def reproduce(
    *,
    runs: int = 100,
    particles: int = 10000,
    seed: int | None = None,
    jobs: int = 1,
    scheduler: Scheduler | None = None,
    comparison: bool = True,
    scenarios_dir: str | Path | None = None,
    sensors: Iterable[int] = SENSOR_COUNTS,
    horizons: Iterable[int] = HORIZONS,
    search: str | None = None,
    grid_size: int = 101,
    mc_samples: int | None = None,
    progress: Callable[[CaseResult], None] | None = None,
    task_progress: Callable[[int, int], None] | None = None,
) -> HernandezResults:
    """Tables 1-2 and the search comparison of Hernandez (2004).

    Every case is planned open loop (``mc_samples`` planner samples, scenario: 1,000; the
    scenarios' search unless ``search``), then ``runs`` PF runs of ``particles`` particles track
    along the planned paths (0: the bounds only); ``seed`` (default: the scenarios') fixes both.
    ``comparison`` re-plans the 1-sensor single-step case on a ``grid_size`` x ``grid_size``
    grid (with 1 among ``sensors``). ``progress`` is called with each case, in order, once all
    are tracked. Scenario files come from ``scenarios_dir`` or the package data.
    """
    if runs < 0 or particles < 1:
        raise ValueError(f"runs must be >= 0 and particles >= 1, got {runs} and {particles}")
    check_jobs(jobs, scheduler)
    counts, horizon_list = check_options(
        sensors=sensors,
        horizons=horizons,
        search=search,
        grid_size=grid_size,
        mc_samples=mc_samples,
        comparison=comparison,
    )
    sdir = find_scenarios_dir(scenarios_dir, "hernandez_*.yaml")
    files = {(n, R): scenario_path(scenario_name(n, R), sdir) for n in counts for R in horizon_list}
    reference = load_scenario(scenario_path(scenario_name(1, 1), sdir))
    compare = comparison and 1 in counts
    # The comparison's grid (and its quadrant, when the cases do not plan the 1-sensor
    # single-step case with the quadrant search) is planned in the cases' plan map.
    has_quadrant = (1, 1) in files and (search or reference.planner.search) == "quadrant"
    extra = []
    if compare:
        kw = {"mc_samples": mc_samples, "seed": reference.seed if seed is None else seed}
        extra = [(reference, {**kw, "search": "grid", "grid_size": grid_size})]
        if not has_quadrant:
            extra.append((reference, {**kw, "search": "quadrant"}))
    tasks = TaskProgress(len(files) * (1 + runs) + len(extra), task_progress)
    run_kw = dict(runs=runs, particles=particles, seed=seed, jobs=jobs, mc_samples=mc_samples)
    scenarios = [load_scenario(files[key]) for key in sorted(files)]
    with connected(scheduler) as cluster:  # one connection for both maps
        cases, extra_plans = _plan_and_track(
            scenarios, search=search, tasks=tasks, scheduler=cluster, extra_plans=extra, **run_kw
        )
    if progress is not None:
        for case in cases:
            progress(case)
    times = reference.dt * np.arange(1, reference.steps + 1)
    res = HernandezResults(runs, particles, cases, None, times)
    if compare:
        quad = res.case(1, 1) if has_quadrant else extra_plans[1]
        assert quad is not None
        res.comparison = SearchComparison(grid_size, quad.plan, extra_plans[0].plan)
        res.prior_samples = prior_samples(reference)
    return res


def format_progress(case: CaseResult) -> str:
    """The one-line progress report of a finished case."""
    s = case.summary()
    return (
        f"[hernandez] {case.plan.sensors} sensor(s), {HORIZON_NAMES[case.plan.horizon]}-step: "
        f"bound ({s['bound_x']:.2f}, {s['bound_y']:.2f}) m, "
        f"{s['evaluations_per_decision']:.0f} evaluations/decision, "
        f"{s['decision_time_s'] * 1e3:.1f} ms/decision"
    )


def _sensors_label(n: int) -> str:
    return f"{n} sensor" + ("s" if n > 1 else "")


def _table1_cell(c: CaseResult | None, axis: int) -> str:
    if c is None:
        return "-"
    b, e = (c.bound_x, c.bound_y)[axis], (c.pf_rmse_x, c.pf_rmse_y)[axis]
    return f"{b:.1f} ({e:.1f})" if e is not None else f"{b:.1f}"


def _format_table1(res: HernandezResults) -> str:
    lines = [
        "Table 1: RMSE bounds averaged over k = 1..30 (PF RMSEs in brackets), metres",
        "ours / paper",
        f"{'':14s}" + "".join(f"{_sensors_label(n):^42s}" for n in SENSOR_COUNTS),
        f"{'Direction':14s}" + "".join(f"{'Single-Step':^21s}{'Two-Step':^21s}" for _ in range(3)),
    ]
    keys = [(n, R) for n in SENSOR_COUNTS for R in HORIZONS]
    for axis, name in ((0, "x-coordinate"), (1, "y-coordinate")):
        ours = [_table1_cell(res.case(*key), axis) for key in keys]
        paper = [f"{p[axis]:.1f} ({p[2 + axis]:.1f})" for p in map(PAPER_TABLE1.get, keys)]
        for label, cells in ((name, ours), ("  paper", paper)):
            lines.append(f"{label:14s}" + "".join(f"{cell:^21s}" for cell in cells))
    return "\n".join(lines)


def _fmt(v: float | None) -> str:
    return "-" if v is None else f"{v:.1f}"


def _format_table2(res: HernandezResults) -> str:
    imp = res.improvements()
    lines = [
        "Table 2: % improvement of two-step over single-step (PF RMSEs in brackets)",
        f"{'Direction':14s}" + "".join(f"{_sensors_label(n):^30s}" for n in SENSOR_COUNTS),
    ]
    for axis, name in ((0, "x-coordinate"), (1, "y-coordinate")):
        row, prow = f"{name:14s}", f"{'  paper':14s}"
        for n in SENSOR_COUNTS:
            v = imp.get(n)
            row += f"{(_fmt(v[axis]) + ' (' + _fmt(v[2 + axis]) + ')') if v else '-':^30s}"
            p = PAPER_TABLE2[n]
            prow += f"{f'{p[axis]:.1f} ({p[2 + axis]:.1f})':^30s}"
        lines += [row, prow]
    return "\n".join(lines)


def _format_comparison(comp: SearchComparison) -> str:
    doc = comp.to_json()
    size = comp.grid_size
    lines = ["Quadrant search vs 101x101 grid, 1 sensor single-step:"]
    for name, d in (("quadrant", doc["quadrant"]), (f"grid {size}x{size}", doc["grid"])):
        lines.append(
            f"  {name:16s} bound ({d['bound_x']:.2f}, {d['bound_y']:.2f}) m, mean b_k "
            f"{d['mean_b_k']:.2f} m, {d['evaluations_per_decision']:.0f} evaluations and "
            f"{d['decision_time_s'] * 1e3:.1f} ms per decision"
        )
    gap = doc["path_separation_m"]
    lines.append(f"  path separation: max {gap['max']:.0f} m, final {gap['final']:.0f} m")
    return "\n".join(lines)


def format_results(res: HernandezResults) -> str:
    """Tables 1 and 2 against the paper's, and the search comparison, as printed."""
    parts = [_format_table1(res), _format_table2(res)]
    if res.comparison is not None:
        parts.append(_format_comparison(res.comparison))
    return "\n\n".join(parts)


def _plot_paths(ax, case: PlannedCase, title: str) -> None:
    tm = case.target_mean
    ax.plot(tm[:, 0], tm[:, 2], "k--", lw=1, label="target (prior mean)")
    for i, pid in enumerate(case.platform_ids):
        ax.plot(case.paths[:, i, 0], case.paths[:, i, 2], "-o", ms=2, label=f"sensor {pid}")
    for k in range(1, len(case.P) + 1, 3):  # 1-sigma ellipses of the position, 10x
        pts = covariance_ellipse(tm[k, [0, 2]], case.P[k - 1][np.ix_([0, 2], [0, 2])], 10.0)
        ax.plot(pts[:, 0], pts[:, 1], color="tab:red", lw=0.7)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(title, fontsize=9)
    ax.set(xlabel="x (m)", ylabel="y (m)")
    ax.legend(fontsize=7)


def _figure2(res: HernandezResults):
    """Fig. 2: prior samples, quadrant and grid paths with 10x PCRLB ellipses, b_k."""
    fig, axs = figure_axes((11, 9), 2, 2)
    X = res.prior_samples
    for k in range(0, X.shape[0], 2):
        axs[0, 0].plot(X[k, :, 0], X[k, :, 2], ",", color="tab:blue", alpha=0.3)
    axs[0, 0].set_title("(a) prior target samples, k = 0, 2, ..., 30", fontsize=9)
    axs[0, 0].set_aspect("equal", adjustable="datalim")
    quad = res.case(1, 1).plan
    _plot_paths(axs[0, 1], quad, "(b) quadrant search, 10x PCRLB ellipses")
    _plot_paths(axs[1, 0], res.comparison.grid, "(c) 101x101 grid search, 10x PCRLB ellipses")
    for case, lab in ((quad, "quadrant"), (res.comparison.grid, "grid 101x101")):
        axs[1, 1].plot(res.times, case.bounds.max(axis=1), label=lab)
    axs[1, 1].set(xlabel="time (s)", ylabel="b_k (m)")
    axs[1, 1].set_title("(d) RMSE bound b_k (eq. 10)", fontsize=9)
    axs[1, 1].legend()
    return fig


def _figure3(res: HernandezResults):
    """Fig. 3: 2-sensor paths single vs two-step, y bound and y PF RMSE."""
    fig, axs = figure_axes((11, 9), 2, 2)
    _plot_paths(axs[0, 0], res.case(2, 1).plan, "(a) 2 sensors, single-step")
    _plot_paths(axs[0, 1], res.case(2, 2).plan, "(b) 2 sensors, two-step")
    for R, lab in ((1, "single-step"), (2, "two-step")):
        c = res.case(2, R)
        axs[1, 0].plot(res.times, c.plan.bounds[:, 1], label=lab)
        if c.rmse is not None:
            axs[1, 1].plot(res.times, c.rmse[:, 1], label=lab)
    axs[1, 0].set_title("(c) y RMSE bound", fontsize=9)
    axs[1, 1].set_title("(d) y PF RMSE", fontsize=9)
    for ax in axs[1]:
        ax.set(xlabel="time (s)", ylabel="m")
        ax.legend()
    return fig


def _figure_all(res: HernandezResults):
    """All cases: b_k and the max(x, y) PF RMSE against time."""
    fig, axs = figure_axes((12, 4.5), 1, 2)
    for c in res.cases:
        lab = f"{c.plan.sensors} sensor(s), {HORIZON_NAMES[c.plan.horizon]}-step"
        (line,) = axs[0].plot(res.times, c.plan.bounds.max(axis=1), label=lab)
        if c.rmse is not None:
            axs[1].plot(res.times, c.rmse.max(axis=1), color=line.get_color(), label=lab)
    axs[0].set_title("b_k = max(x, y) RMSE bound")
    axs[1].set_title("max(x, y) PF RMSE")
    for ax in axs:
        ax.set(xlabel="time (s)", ylabel="m", yscale="log")
        ax.legend(fontsize=7)
    return fig


def _render(task: tuple[str, Callable, HernandezResults, Path]) -> Path:
    """One figure of :func:`save_figures` (a task of its map)."""
    file, draw, res, out = task
    return write_figures([(file, partial(draw, res))], out, dpi=110)[0]


def save_figures(res: HernandezResults, out: str | Path, jobs: int = 1) -> list[Path]:
    """Write the PNG figures into ``out``: Fig. 2 (with the comparison and the 1-sensor
    single-step case), Fig. 3 (with both 2-sensor cases) and all cases, on ``jobs``
    processes (about 0.4 s each); returns the files."""
    figures = [("bounds_and_rmse_all_cases.png", _figure_all)]
    if res.case(2, 1) is not None and res.case(2, 2) is not None:
        figures.insert(0, ("fig3_2sensors_single_vs_two.png", _figure3))
    if res.comparison is not None and res.case(1, 1) is not None:
        figures.insert(0, ("fig2_1sensor_quadrant_vs_grid.png", _figure2))
    return parallel_map(_render, [(*f, res, Path(out)) for f in figures], jobs)


def _options(parser: argparse.ArgumentParser) -> None:
    add = parser.add_argument
    add(
        "--particles",
        type=int_in_range(1, limits.MAX_PARTICLES),
        default=10000,
        help="PF particles (10,000)",
    )
    add(
        "--mc-samples",
        type=int_in_range(1, limits.MAX_SAMPLES),
        help="planner Monte Carlo samples (scenario: 1000)",
    )
    add("--sensors", default="1,2,3", help="sensor counts, e.g. 1,2,3")
    add("--horizons", default="1,2", help="planning horizons, 1 and/or 2")
    add("--search", choices=SEARCHES, help="override the scenarios' search (quadrant)")
    add(
        "--grid-size",
        type=int_in_range(2, limits.MAX_GRID_SIZE),
        default=101,
        help="grid of the comparison (101)",
    )
    add("--no-comparison", action="store_true", help="skip the quadrant vs 101x101 grid comparison")
    add("--seed", type=int_in_range(0, limits.MAX_SEED), help="seed (scenario seed)")
    add("--scenarios", help="directory with hernandez_*.yaml")


def _check_cli(args: argparse.Namespace) -> None:
    """Adds ``sensor_counts`` and ``horizon_list`` (:func:`check_options`)."""
    args.sensor_counts, args.horizon_list = check_options(
        sensors=args.sensors.split(","),
        horizons=args.horizons.split(","),
        search=args.search,
        grid_size=args.grid_size,
        mc_samples=args.mc_samples,
        comparison=not args.no_comparison,
    )


def _arguments(args: argparse.Namespace) -> dict:
    """The arguments of :func:`reproduce` the options set (besides the runs and workers)."""
    return dict(
        particles=args.particles,
        seed=args.seed,
        comparison=not args.no_comparison,
        scenarios_dir=args.scenarios,
        sensors=args.sensor_counts,
        horizons=args.horizon_list,
        search=args.search,
        grid_size=args.grid_size,
        mc_samples=args.mc_samples,
        progress=lambda case: print(format_progress(case), file=sys.stderr, flush=True),
    )


def _document(res: HernandezResults, figures: list[Path], wall_time_s: float) -> dict:
    """``res.to_json()`` with the figure files, if any."""
    doc = res.to_json()
    if figures:
        doc["figures"] = [str(f) for f in figures]
    return doc


REPRODUCTION = Reproduction(
    "hernandez",
    "Reproduce Hernandez (2004) Tables 1-2 and Figs. 2-3.",
    RunsOption(
        0, 100, "Monte Carlo PF runs per case (100; 0: the bounds only)", "0: the bounds only"
    ),
    report=format_results,
    figures=lambda res, args: save_figures(res, args.out, jobs=args.jobs),
    options=_options,
    check=_check_cli,
    arguments=_arguments,
    document=_document,
)
_parse = REPRODUCTION.parse
main = REPRODUCTION.main


if __name__ == "__main__":
    raise SystemExit(main())
