"""Reproduce Ramdaras, Absil, van Genderen (ICCRTS 2010) sec. 5-6 (``activetrack reproduce
ramdaras``).

The paper's cases (``CASES``; Fig. 7-12 and Pd < 1 variants of Cases 2 and 3) run through the
closed loop (EKF tracker, MRE positioning and selection, eq. 23-27) over seeded Monte Carlo
runs, with MRE selection against the baselines (trace, random, fixed, all sensors): selection
counts, time-averaged det(P_pos) of the EKF's P_{k|k}, margins of MRE over the baselines, the
selection criteria (eq. 24-26) and, for Pd < 1, the MRE bound against the filter's covariance.
See docs/ramdaras.md.
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from activetrack.bounds.costs import position_determinant
from activetrack.bounds.mre import mre_update
from activetrack.checks import require_int
from activetrack.closed_loop.loop import run_once
from activetrack.limits import MAX_RUNS
from activetrack.montecarlo import Progress, Scheduler, TaskProgress, check_jobs
from activetrack.planning.selection import expected_update
from activetrack.plots import write_figures
from activetrack.scenarios import build_motion_model, load_scenario, parse_scenario
from activetrack.scenarios.build import build_sensor
from activetrack.scenarios.schema import Scenario
from activetrack_experiments.paths import scenario_path
from activetrack_experiments.reproduction import (
    Reproduction,
    RunsOption,
    figure_axes,
    map_groups,
    split,
)

PAPER = "Ramdaras, Absil, van Genderen, ICCRTS 2010"
# (key, scenario file, label). Case 1 (3, 9) is the Case 1 of Fig. 10-12.
CASES = (
    ("case1_0_0", "ramdaras_case1_0_0.yaml", "Case 1, co-located at (0, 0) km"),
    ("case1_3_9", "ramdaras_case1_3_9.yaml", "Case 1, co-located at (3, 9) km"),
    ("case1_10_8", "ramdaras_case1_10_8.yaml", "Case 1, co-located at (10, 8) km"),
    ("case2", "ramdaras_case2.yaml", "Case 2, distributed stationary"),
    ("case3", "ramdaras_case3.yaml", "Case 3, moving, positioning (d_max 5)"),
    ("case2_pd", "ramdaras_case2_pd.yaml", "Case 2, Pd = (0.9, 0.8, 0.7)"),
    ("case3_pd", "ramdaras_case3_pd.yaml", "Case 3, Pd = (0.9, 0.8, 0.7)"),
)
CASE_KEYS = tuple(key for key, _, _ in CASES)
CASE1_CASES = ("case1_0_0", "case1_3_9", "case1_10_8")
FIG12_CASES = ("case1_3_9", "case2", "case3")
PD_CASES = ("case2_pd", "case3_pd")
STRATEGIES = ("mre", "trace", "random", "fixed_s1", "fixed_s2", "fixed_s3", "all")
QUICK_STRATEGIES = ("mre", "trace", "random", "fixed_s2", "fixed_s3", "all")
BASELINES = ("random", "fixed_s1", "fixed_s2", "fixed_s3")  # MRE must beat these
CRITERIA = ("det_pos", "heading", "range", "doppler", "bearing")
CRITERIA_CASE = "case2"
BOUND_MIN_RUNS = 10  # the bound checks run max(runs, 10) times
DRAWS = 40000  # detection sequences of the exact bound check


def load_case(case: str, scenarios_dir: str | Path | None = None) -> Scenario:
    """The scenario of case ``case`` (``CASE_KEYS``) from ``scenarios_dir`` (default: the
    package's)."""
    files = {key: name for key, name, _ in CASES}
    if case not in files:
        raise ValueError(f"case must be one of {tuple(files)}, got {case!r}")
    return load_scenario(scenario_path(files[case], scenarios_dir))


def variant(
    scenario: Scenario,
    strategy: str = "mre",
    *,
    criterion: str | None = None,
    mode: str | None = None,
    steps: int | None = None,
    seed: int | None = None,
) -> Scenario:
    """The scenario with another selection strategy (``STRATEGIES``; ``fixed_<sensor>``),
    criterion (selection and positioning alike, as the paper recommends), planner mode,
    length or seed. Re-validated like a loaded file."""
    d = scenario.model_dump()
    sel = d["planner"]["selection"]
    if strategy == "all":
        sel["enabled"] = False
    elif strategy.startswith("fixed_"):
        sel.update(enabled=True, strategy="fixed", fixed_sensor=strategy.removeprefix("fixed_"))
    elif strategy in ("mre", "trace", "random"):
        sel.update(enabled=True, strategy=strategy)
    else:
        raise ValueError(
            f"strategy must be one of {STRATEGIES} or fixed_<sensor>, got {strategy!r}"
        )
    if criterion is not None:
        sel["criterion"] = criterion
        d["planner"]["criterion"] = criterion
    if mode is not None:
        d["planner"]["mode"] = mode
    d.update({k: int(v) for k, v in (("steps", steps), ("seed", seed)) if v is not None})
    d["name"] = f"{scenario.name}-{strategy}" + (f"-{criterion}" if criterion else "")
    return parse_scenario(d, d["name"])


@dataclass
class RunTrace:
    """One closed-loop run, epochs 0..K (selection / detection rows for epochs 1..K)."""

    truth: np.ndarray  # (K+1, 4)
    estimate: np.ndarray  # (K+1, 4)
    cov: np.ndarray  # (K+1, 4, 4) the EKF's P_{k|k}
    paths: np.ndarray  # (K+1, P, 4)
    platform_ids: tuple[str, ...]
    sensor_ids: tuple[str, ...]
    measured: np.ndarray  # (K, S) bool: sensor measured (was selected) at epoch k
    detected: np.ndarray  # (K, S) bool: and detected the target
    planner_cov: np.ndarray  # (K, 4, 4) the planner's expected P_{k|k} (MRE), NaN if none
    tracker_missed: int = 0
    wall_time_s: float = 0.0

    @property
    def det_pos(self) -> np.ndarray:
        """det(P_{k|k})_pos (eq. 24 applied to the filter's covariance), k = 1..K."""
        return position_determinant(self.cov[1:])

    @property
    def missed(self) -> int:
        return int((self.measured & ~self.detected).sum())


def run_traced(scenario: Scenario, run: int | None = None) -> RunTrace:
    """One closed-loop run (:func:`activetrack.closed_loop.loop.run_once`) with the
    planner's MRE covariance of each decision."""
    r = run_once(scenario, run)
    estimate, cov = r.track_series()
    planner_cov = np.full((scenario.steps, 4, 4), np.nan)
    for k, decision in enumerate(r.decisions):
        if "mre_updated_cov" in decision.extra:
            planner_cov[k] = decision.extra["mre_updated_cov"]
    return RunTrace(
        truth=r.truth[:, 0],
        estimate=estimate,
        cov=cov,
        paths=r.platform_paths,
        platform_ids=r.platform_ids,
        sensor_ids=tuple(s.id for p in scenario.platforms for s in p.sensors),
        measured=r.looked,
        detected=r.detected,
        planner_cov=planner_cov,
        tracker_missed=r.missed_detections(),
        wall_time_s=r.wall_time_s,
    )


def _recursion_inputs(scenario: Scenario, trace: RunTrace, mask: np.ndarray):
    """F, Q, P_{0|0} and, for each epoch k = 1..K, the ``(sensor, platform pv at k)`` of the
    sensors ``mask[k - 1]`` marks (``trace.measured`` or ``trace.detected``, (K, S))."""
    model = build_motion_model(scenario.target.motion)
    F, Q = model.transition_matrix(scenario.dt), model.process_noise(scenario.dt)
    sensors = {s.id: (p.id, build_sensor(s)) for p in scenario.platforms for s in p.sensors}
    column = {pid: j for j, pid in enumerate(trace.platform_ids)}
    epochs = [
        [
            (sensors[sid][1], trace.paths[k, column[sensors[sid][0]]])
            for j, sid in enumerate(trace.sensor_ids)
            if mask[k - 1, j]
        ]
        for k in range(1, scenario.steps + 1)
    ]
    return F, Q, scenario.target.prior.covariance(), epochs


def mre_path_bound(scenario: Scenario, trace: RunTrace) -> np.ndarray:
    """The MRE recursion (eq. 23) along a run: the expected P_{k|k} ``(K, 4, 4)`` from the
    prior, with the sensors that measured at each epoch at their flown positions and H
    (eq. 13) at the run's true target states (an evaluation, like a PCRLB at the truth).

    Given the truth and a schedule that does not depend on the detections, it bounds the mean
    of the filter's P_{k|k} over the detection draws from above: the Kalman update
    P -> (P^-1 + H^T R^-1 H)^-1 is concave and monotone, so by Jensen E[P_{k|k}] <= P^MRE_{k|k}
    (equality when pd = 1).
    """
    F, Q, P, epochs = _recursion_inputs(scenario, trace, trace.measured)
    out = []
    for k, used in enumerate(epochs, start=1):
        P = F @ P @ F.T + Q
        if used:
            models = [sensor for sensor, _ in used]
            pvs = np.stack([s for _, s in used])
            P = expected_update(0.5 * (P + P.T), trace.truth[k], models, pvs)
        out.append(P)
    return np.array(out)


def _run_task(args) -> RunTrace:
    scenario_dict, run = args
    return run_traced(parse_scenario(scenario_dict, scenario_dict["name"]), run)


def run_groups(
    groups: Sequence[tuple[Scenario, int]],
    jobs: int = 1,
    progress: Progress | None = None,
    scheduler: Scheduler | None = None,
) -> list[list[RunTrace]]:
    """For each ``(scenario, runs)``, its ``runs`` seeded runs (run r: SeedSequence([seed,
    r])), all in one :func:`activetrack.montecarlo.parallel_map`."""
    for _, runs in groups:
        if runs < 1:
            raise ValueError(f"runs must be >= 1, got {runs}")
    tasks = [[(scenario.model_dump(), r) for r in range(runs)] for scenario, runs in groups]
    return map_groups(_run_task, tasks, jobs, progress, scheduler)


def run_runs(
    scenario: Scenario, runs: int, jobs: int = 1, scheduler: Scheduler | None = None
) -> list[RunTrace]:
    """``runs`` seeded runs (run r: SeedSequence([seed, r]))."""
    return run_groups([(scenario, runs)], jobs, scheduler=scheduler)[0]


@dataclass
class CaseResult:
    """Monte Carlo summary of one case under one strategy (and criterion)."""

    case: str
    strategy: str
    criterion: str
    runs: int
    sensor_ids: tuple[str, ...]
    selection_counts: dict  # sensor -> measurements ordered over all runs
    det_t: np.ndarray  # (runs, K) det(P_{k|k})_pos
    bound_det_t: np.ndarray  # (runs, K) det_pos of the MRE recursion along the run
    missed: int
    measured: int
    tracker_missed: int
    switch_rate: float  # fraction of epochs whose single selected sensor differs from the last
    traces: list = field(default_factory=list, repr=False)

    @property
    def mean_det_pos(self) -> float:
        """Time-averaged det(P_pos), averaged over runs."""
        return float(self.det_t.mean(axis=1).mean())

    @property
    def std_det_pos(self) -> float:
        """Spread over runs of the time-averaged det(P_pos)."""
        return float(self.det_t.mean(axis=1).std(ddof=1)) if self.runs > 1 else 0.0

    def to_json(self) -> dict:
        return {
            "case": self.case,
            "strategy": self.strategy,
            "criterion": self.criterion,
            "runs": self.runs,
            "selection_counts": dict(self.selection_counts),
            "selection_counts_per_run": {
                s: n / self.runs for s, n in self.selection_counts.items()
            },
            "mean_det_pos": self.mean_det_pos,
            "std_det_pos": self.std_det_pos,
            "mre_bound_mean_det_pos": float(self.bound_det_t.mean()),
            "det_pos_t": self.det_t.mean(axis=0).tolist(),
            "missed_detections": self.missed,
            "measurements": self.measured,
            "switch_rate": self.switch_rate,
        }

    def row(self) -> dict:
        """One flat table row: the scalars of :meth:`to_json`, a ``count_<sensor>`` and
        ``count_per_run_<sensor>`` column per sensor and the tracker's missed count."""
        counts = {f"count_{s}": n for s, n in self.selection_counts.items()}
        per_run = {f"count_per_run_{s}": n / self.runs for s, n in self.selection_counts.items()}
        scalars = {k: v for k, v in self.to_json().items() if not isinstance(v, dict | list)}
        return {**scalars, **counts, **per_run, "tracker_missed_detections": self.tracker_missed}


def summarize_case(case: str, strategy: str, criterion: str, scenario, traces) -> CaseResult:
    sensor_ids = traces[0].sensor_ids
    counts = Counter()
    switches, epochs = 0, 0
    for t in traces:
        for j, s in enumerate(sensor_ids):
            counts[s] += int(t.measured[:, j].sum())
        single = t.measured.sum(axis=1) == 1
        sel = np.argmax(t.measured, axis=1)
        both = single[1:] & single[:-1]
        switches += int((sel[1:] != sel[:-1])[both].sum())
        epochs += int(both.sum())
    return CaseResult(
        case=case,
        strategy=strategy,
        criterion=criterion,
        runs=len(traces),
        sensor_ids=sensor_ids,
        selection_counts={s: counts[s] for s in sensor_ids},
        det_t=np.stack([t.det_pos for t in traces]),
        bound_det_t=np.stack([position_determinant(mre_path_bound(scenario, t)) for t in traces]),
        missed=sum(t.missed for t in traces),
        measured=int(sum(t.measured.sum() for t in traces)),
        tracker_missed=sum(t.tracker_missed for t in traces),
        switch_rate=switches / epochs if epochs else float("nan"),
        traces=list(traces),
    )


@dataclass
class _Spec:
    """One Monte Carlo group of :func:`reproduce`: a case variant and its number of runs."""

    case: str
    strategy: str
    criterion: str | None
    scenario: Scenario
    runs: int

    def summarize(self, traces: list[RunTrace]) -> CaseResult:
        crit = self.criterion or self.scenario.planner.selection.criterion
        return summarize_case(self.case, self.strategy, crit, self.scenario, traces)


def _case_spec(
    case, strategy="mre", *, runs=1, criterion=None, scenarios_dir=None, scenario=None, **change
) -> _Spec:
    """The group of ``case`` (its scenario file, or ``scenario``) as :func:`variant` changes it
    (``change``: mode, steps, seed)."""
    base = load_case(case, scenarios_dir) if scenario is None else scenario
    sc = variant(base, strategy, criterion=criterion, **change)
    return _Spec(case, strategy, criterion, sc, int(runs))


def run_case(
    case: str, strategy: str = "mre", *, runs: int = 1, jobs: int = 1, scheduler=None, **change
) -> CaseResult:
    """Load a case, apply the :func:`variant` (``change``: criterion, mode, steps, seed;
    ``scenarios_dir``), run it ``runs`` times (:func:`run_runs`) and summarise."""
    spec = _case_spec(case, strategy, runs=runs, **change)
    return spec.summarize(run_runs(spec.scenario, spec.runs, jobs, scheduler))


def margins(results: list[CaseResult]) -> list[dict]:
    """MRE against each other strategy of the same case: relative reduction of det_pos."""
    by = {(r.case, r.strategy): r for r in results if r.criterion == "det_pos"}
    return [
        {
            "case": case,
            "baseline": strategy,
            "mre_mean_det_pos": mre.mean_det_pos,
            "baseline_mean_det_pos": r.mean_det_pos,
            "reduction": 1.0 - mre.mean_det_pos / r.mean_det_pos,
            "mre_better": mre.mean_det_pos < r.mean_det_pos,
        }
        for (case, strategy), r in by.items()
        if strategy != "mre" and (mre := by.get((case, "mre"))) is not None
    ]


def detection_average(
    scenario: Scenario, trace: RunTrace, draws: int, rng: np.random.Generator
) -> np.ndarray:
    """E[P_{k|k}] over ``draws`` detection sequences for a run's truth and schedule
    ``(K, 4, 4)``: the Riccati recursion with H at the true states and each measuring sensor
    detecting with its pd, vectorised over the draws (mre_update with pd in {0, 1})."""
    F, Q, P0, epochs = _recursion_inputs(scenario, trace, trace.measured)
    P = np.broadcast_to(P0, (int(draws), 4, 4)).copy()
    out = []
    for k, used in enumerate(epochs, start=1):
        P = F @ P @ F.T + Q
        for sensor, s in used:
            hit = sensor.in_range(trace.truth[k], s) & (rng.random(int(draws)) < sensor.pd)
            P = mre_update(P, sensor.jacobian(trace.truth[k], s), sensor.R, hit.astype(float))
        out.append(P.mean(axis=0))
    return np.array(out)


@dataclass
class BoundCheck:
    """Pd < 1: the MRE (eq. 23) against the filter's covariance on one fixed schedule.

    Open-loop planning makes the schedule the same in every run, independent of the
    detections, so for each truth E[P_{k|k}] <= P^MRE_{k|k} (Loewner order; see
    :func:`mre_path_bound`). Checked on the EKF's mean P_{k|k} over the runs against the mean
    MRE (heavy-tailed, so on the time average), and for run 0 on the exact average over
    ``draws`` detection sequences, epoch by epoch.
    """

    case: str
    runs: int
    draws: int
    filter_det_t: np.ndarray  # (K,) det_pos of the EKF's P_{k|k} averaged over runs
    mre_det_t: np.ndarray  # (K,) det_pos of the MRE along each run's truth, averaged
    draws_det_t: np.ndarray  # (K,) det_pos of E[P_{k|k}] over detection draws, run 0
    mre0_det_t: np.ndarray  # (K,) det_pos of the MRE of run 0
    min_eig_gap: float  # min_k smallest eigenvalue of (P_MRE - E[P])_pos / tr(P_MRE)_pos, run 0
    ekf_vs_riccati: float  # max relative |det_pos| difference EKF vs Riccati at truth, run 0
    missed: int
    measured: int
    tracker_missed: int

    @property
    def max_draw_ratio(self) -> float:
        return float(np.max(self.draws_det_t / self.mre0_det_t))

    def to_json(self) -> dict:
        return {
            "case": self.case,
            "runs": self.runs,
            "draws": self.draws,
            "filter_mean_det_pos": float(self.filter_det_t.mean()),
            "mre_mean_det_pos": float(self.mre_det_t.mean()),
            "max_detection_average_to_mre_ratio": self.max_draw_ratio,
            "min_relative_eigen_gap": self.min_eig_gap,
            "ekf_vs_riccati_at_truth": self.ekf_vs_riccati,
            "missed_detections": self.missed,
            "tracker_missed_detections": self.tracker_missed,
            "measurements": self.measured,
        }


def summarize_bound(case: str, scenario: Scenario, traces, draws: int = DRAWS) -> BoundCheck:
    """:class:`BoundCheck` of the open-loop MRE runs ``traces``."""
    for t in traces[1:]:
        if not np.array_equal(t.measured, traces[0].measured):
            raise RuntimeError("open-loop schedule differs between runs")
    mre = np.array([mre_path_bound(scenario, t) for t in traces])  # (runs, K, 4, 4)
    t0 = traces[0]
    avg = detection_average(scenario, t0, draws, np.random.default_rng(scenario.seed))
    riccati = detection_average_realized(scenario, t0)
    idx = np.ix_([0, 2], [0, 2])
    gaps = [
        np.linalg.eigvalsh(B[idx] - A[idx]).min() / np.trace(B[idx])
        for A, B in zip(avg, mre[0], strict=True)
    ]
    ekf = position_determinant(t0.cov[1:])
    return BoundCheck(
        case=case,
        runs=len(traces),
        draws=int(draws),
        filter_det_t=position_determinant(np.mean([t.cov[1:] for t in traces], axis=0)),
        mre_det_t=position_determinant(mre.mean(axis=0)),
        draws_det_t=position_determinant(avg),
        mre0_det_t=position_determinant(mre[0]),
        min_eig_gap=float(min(gaps)),
        ekf_vs_riccati=float(np.max(np.abs(ekf / position_determinant(riccati) - 1.0))),
        missed=sum(t.missed for t in traces),
        measured=int(sum(t.measured.sum() for t in traces)),
        tracker_missed=sum(t.tracker_missed for t in traces),
    )


def bound_check(
    case: str, runs: int, *, draws: int = DRAWS, jobs: int = 1, scheduler=None, **change
) -> BoundCheck:
    """:class:`BoundCheck` of ``runs`` runs of ``case`` with open-loop MRE planning
    (``change``: steps, seed; ``scenarios_dir``)."""
    spec = _case_spec(case, runs=runs, mode="open_loop", **change)
    traces = run_runs(spec.scenario, spec.runs, jobs, scheduler)
    return summarize_bound(case, spec.scenario, traces, draws)


def detection_average_realized(scenario: Scenario, trace: RunTrace) -> np.ndarray:
    """The Riccati recursion of a run's own detections with H at the truth ``(K, 4, 4)``:
    what the EKF's P_{k|k} is up to its linearisation at the estimate."""
    F, Q, P, epochs = _recursion_inputs(scenario, trace, trace.detected)
    out = []
    for k, used in enumerate(epochs, start=1):
        P = F @ P @ F.T + Q
        for sensor, s in used:
            P = mre_update(P, sensor.jacobian(trace.truth[k], s), sensor.R, 1.0)
        out.append(P)
    return np.array(out)


@dataclass
class RamdarasResults:
    """What :func:`reproduce` computed: the cases under each strategy, the criteria study
    (empty without ``CRITERIA_CASE``), the Pd < 1 bound checks (empty without ``PD_CASES``) and
    the margins of MRE selection over the other strategies."""

    runs: int
    case_keys: tuple[str, ...]
    strategies: tuple[str, ...]
    cases: list[CaseResult]
    criteria: list[CaseResult]
    checks: list[BoundCheck]
    margins: list[dict]
    wall_time_s: float = 0.0

    def mre(self) -> dict[str, CaseResult]:
        """MRE selection (det_pos criterion) per case."""
        return {r.case: r for r in self.cases if r.strategy == "mre" and r.criterion == "det_pos"}

    def get(self, case: str, strategy: str = "mre") -> CaseResult:
        """The result of ``case`` under ``strategy``."""
        for r in self.cases:
            if r.case == case and r.strategy == strategy:
                return r
        raise KeyError(f"no result for case {case!r}, strategy {strategy!r}")

    def table(self) -> list[dict]:
        """One flat row (:meth:`CaseResult.row`) per case and strategy (``section`` "cases")
        and per criterion of the criteria study ("criteria")."""
        return [
            {"section": section, **r.row()}
            for section, results in (("cases", self.cases), ("criteria", self.criteria))
            for r in results
        ]

    def to_json(self, figures: Sequence[str | Path] = (), wall_time_s: float | None = None) -> dict:
        """The document ``--json`` writes (``figures``: the files written, if any)."""
        return {
            "paper": PAPER,
            "runs": self.runs,
            "cases": [r.to_json() for r in self.cases],
            "margins": self.margins,
            "criteria": [r.to_json() for r in self.criteria],
            "bound_checks": [c.to_json() for c in self.checks],
            "figures": [str(f) for f in figures],
            "wall_time_s": self.wall_time_s if wall_time_s is None else wall_time_s,
        }


def _case_keys(cases: str | Sequence[str] | None, option: str = "cases") -> tuple[str, ...]:
    keys = CASE_KEYS if cases is None else (cases,) if isinstance(cases, str) else tuple(cases)
    bad = [c for c in keys if c not in CASE_KEYS]
    if bad or not keys:
        raise ValueError(f"{option}: unknown {bad}; choose from {list(CASE_KEYS)}")
    return keys


def _check_args(
    runs, jobs, cases, strategies, scheduler=None
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    require_int("runs", runs, 1, MAX_RUNS)
    check_jobs(jobs, scheduler)
    keys = _case_keys(cases)
    for s in strategies:
        if s not in STRATEGIES:
            raise ValueError(f"strategies: {s!r} is not one of {STRATEGIES}")
    return keys, tuple(strategies)


def _specs(
    keys, strategies, runs, bound_runs, *, scenarios_dir, **kw
) -> tuple[list[_Spec], list[_Spec], list[_Spec]]:
    """The groups of :func:`reproduce`: cases x strategies, the criteria study and the
    open-loop bound checks."""
    loaded = {case: load_case(case, scenarios_dir) for case in keys}
    cases = [
        _case_spec(case, s, runs=runs, scenario=loaded[case], **kw)
        for case in keys
        for s in strategies
    ]
    criteria = [
        _case_spec(
            CRITERIA_CASE, "mre", runs=runs, criterion=c, scenario=loaded[CRITERIA_CASE], **kw
        )
        for c in (CRITERIA if CRITERIA_CASE in keys else ())
    ]
    checks = [
        _case_spec(case, runs=bound_runs, mode="open_loop", scenario=loaded[case], **kw)
        for case in PD_CASES
        if case in keys
    ]
    return cases, criteria, checks


def reproduce(
    runs: int | None = None,
    *,
    seed: int | None = None,
    jobs: int = 1,
    scheduler: Scheduler | None = None,
    quick: bool = False,
    cases: Sequence[str] | None = None,
    scenarios_dir: str | Path | None = None,
    strategies: Sequence[str] | None = None,
    steps: int | None = None,
    bound_runs: int | None = None,
    draws: int = DRAWS,
    task_progress: Callable[[int, int], None] | None = None,
) -> RamdarasResults:
    """Ramdaras et al. (2010) sec. 5-6: every case in ``cases`` (``CASE_KEYS``, default all)
    under every strategy (default ``STRATEGIES``, ``QUICK_STRATEGIES`` when ``quick``), the
    selection criteria on ``CRITERIA_CASE`` and, for the Pd < 1 cases, the bound check with
    ``bound_runs`` open-loop runs (default max(runs, 10)) and ``draws`` detection sequences.

    ``runs`` per case and strategy (default 20, 3 when ``quick``), all in one parallel map;
    ``seed`` replaces the scenario files' (run r draws from SeedSequence([seed, r])); ``steps``
    shortens the runs (the paper: 100 epochs); ``scenarios_dir`` holds ramdaras_*.yaml
    (default: the package's).
    """
    start = time.perf_counter()
    runs = (3 if quick else 20) if runs is None else runs
    if strategies is None:
        strategies = QUICK_STRATEGIES if quick else STRATEGIES
    keys, strategies = _check_args(runs, jobs, cases, strategies, scheduler)
    bound_runs = max(runs, BOUND_MIN_RUNS) if bound_runs is None else bound_runs
    kw = dict(steps=steps, seed=seed, scenarios_dir=scenarios_dir)
    case_specs, crit_specs, bound_specs = _specs(keys, strategies, runs, bound_runs, **kw)
    specs = case_specs + crit_specs + bound_specs
    tasks = TaskProgress(sum(s.runs for s in specs), task_progress)
    traced = run_groups([(s.scenario, s.runs) for s in specs], jobs, tasks.of_map(), scheduler)
    sizes = [len(case_specs), len(crit_specs), len(bound_specs)]
    case_traces, crit_traces, bound_traces = split(traced, sizes)
    results = [s.summarize(t) for s, t in zip(case_specs, case_traces, strict=True)]
    criteria = [s.summarize(t) for s, t in zip(crit_specs, crit_traces, strict=True)]
    checks = [
        summarize_bound(s.case, s.scenario, t, draws)
        for s, t in zip(bound_specs, bound_traces, strict=True)
    ]
    return RamdarasResults(
        runs=runs,
        case_keys=keys,
        strategies=strategies,
        cases=results,
        criteria=criteria,
        checks=checks,
        margins=margins(results),
        wall_time_s=time.perf_counter() - start,
    )


def _counts(r: CaseResult) -> str:
    return " ".join(f"{s}:{n / r.runs:5.1f}" for s, n in r.selection_counts.items())


def format_results(results: list[CaseResult]) -> str:
    lines = [
        "Selection counts per run (epochs each sensor measured, of K = 100) and time-averaged",
        "det(P_pos) of the EKF's P_{k|k} (m^4), mean +- std over runs",
        f"{'case':12s} {'strategy':10s} {'counts per run':32s} {'mean det_pos':>14s} "
        f"{'std':>11s} {'missed':>7s}",
    ]
    for r in results:
        lines.append(
            f"{r.case:12s} {r.strategy:10s} {_counts(r):32s} {r.mean_det_pos:14.1f} "
            f"{r.std_det_pos:11.1f} {r.missed:7d}"
        )
    return "\n".join(lines)


def format_margins(rows: list[dict]) -> str:
    lines = ["MRE selection vs baselines: det_pos reduction 1 - MRE / baseline"]
    for m in rows:
        flag = "MRE better" if m["mre_better"] else "baseline better"
        lines.append(
            f"  {m['case']:12s} vs {m['baseline']:9s} {m['baseline_mean_det_pos']:14.1f} -> "
            f"{m['mre_mean_det_pos']:12.1f}  ({100 * m['reduction']:6.1f} %, {flag})"
        )
    return "\n".join(lines)


def _claim_lines(results: list[CaseResult]) -> list[str]:
    """Fig. 12 (which case is lowest) and Fig. 8 (Case 1: s1 never, s2 and s3 alternate)."""
    mre = {r.case: r for r in results if r.strategy == "mre"}
    lines = []
    fig12 = [c for c in FIG12_CASES if c in mre]
    if fig12:
        best = min(fig12, key=lambda c: mre[c].mean_det_pos)
        lines += [
            "",
            "Fig. 12 cases, MRE selection: "
            + ", ".join(f"{c} {mre[c].mean_det_pos:.1f}" for c in fig12)
            + f"  -> lowest: {best} (paper: Case 3)",
        ]
    for key in CASE1_CASES:
        if key in mre:
            r = mre[key]
            lines.append(
                f"{key}: s1 selected {r.selection_counts.get('s1', 0)} times in {r.runs} runs; "
                f"s2/s3 alternate on {100 * r.switch_rate:.0f} % of epochs (paper: s1 never, "
                "s2 and s3 alternate)"
            )
    return lines


def format_criteria(criteria: list[CaseResult]) -> str:
    lines = [f"Selection criteria (eq. 24-26) on {CRITERIA_CASE}, MRE selection, counts per run"]
    for r in criteria:
        lines.append(f"  {r.criterion:8s} {_counts(r)}   mean det_pos {r.mean_det_pos:10.1f}")
    return "\n".join(lines)


def format_bound_checks(checks: list[BoundCheck], results: list[CaseResult]) -> str:
    """The bound checks and, for their cases, the renewal MRE runs of ``results``."""
    lines = ["Pd < 1: open-loop MRE schedule (same in every run); mean EKF P_k|k vs MRE (eq. 23)"]
    for c in checks:
        lines.append(
            f"  {c.case:9s} missed {c.missed}/{c.measured} detections (tracker counted "
            f"{c.tracker_missed}); time-avg det_pos: mean EKF P {c.filter_det_t.mean():.1f} "
            f"<= MRE {c.mre_det_t.mean():.1f} ({c.runs} runs)"
        )
        lines.append(
            f"  {'':9s} run 0, E over {c.draws} detection draws / MRE: max det ratio "
            f"{c.max_draw_ratio:.4f} (<= 1 up to Monte Carlo error), min eigen gap "
            f"{c.min_eig_gap:+.1e}; EKF vs Riccati at truth {100 * c.ekf_vs_riccati:.1f} %"
        )
    pd_cases = [c.case for c in checks]
    for r in results:
        if r.case in pd_cases and r.strategy == "mre":
            lines.append(
                f"  {r.case:9s} renewal MRE selection: missed {r.missed}/{r.measured} "
                f"(tracker counted {r.tracker_missed}); time-avg det_pos filter "
                f"{r.mean_det_pos:.1f}, MRE along the runs' schedules "
                f"{r.bound_det_t.mean():.1f}"
            )
    return "\n".join(lines)


def format_report(res: RamdarasResults) -> str:
    """The text ``activetrack reproduce ramdaras`` prints (without figures and wall time)."""
    lines = [
        f"Ramdaras et al. (2010), {res.runs} Monte Carlo run(s) per case and strategy",
        format_results(res.cases),
        "",
        format_margins(res.margins),
        *_claim_lines(res.cases),
    ]
    if res.criteria:
        lines += ["", format_criteria(res.criteria)]
    if res.checks:
        lines += ["", format_bound_checks(res.checks, res.cases)]
    return "\n".join(lines)


def _fig_tracks(mre: dict[str, CaseResult]):
    """Fig. 7/10: truth and sensor paths of run 0."""
    keys = [c for c in ("case1_3_9", "case2", "case3", "case3_pd") if c in mre]
    if not keys:
        return None
    fig, axes = figure_axes((4.5 * len(keys), 4.5), 1, len(keys), squeeze=False)
    for ax, key in zip(axes[0], keys, strict=True):
        t = mre[key].traces[0]
        ax.plot(t.truth[:, 0] / 1e3, t.truth[:, 2] / 1e3, "k-", label="target (truth)")
        for j in range(len(t.platform_ids)):
            p = t.paths[:, j]
            ax.plot(p[:, 0] / 1e3, p[:, 2] / 1e3, ".-", ms=3, label=f"{t.sensor_ids[j]}")
            ax.plot(p[0, 0] / 1e3, p[0, 2] / 1e3, "o", color=ax.lines[-1].get_color())
        ax.set(xlim=(-0.5, 13), ylim=(-0.5, 13), xlabel="x (km)", ylabel="y (km)", title=key)
        ax.set_aspect("equal")
        ax.legend(fontsize="small")
    return fig


def _fig_timelines(mre: dict[str, CaseResult]):
    """Fig. 8/11: which sensor measured when in run 0, missed detections marked."""
    keys = [c for c in CASE_KEYS if c in mre]
    if not keys:
        return None
    fig, axes = figure_axes((9, 1.3 * len(keys)), len(keys), 1, sharex=True, squeeze=False)
    for ax, key in zip(axes[:, 0], keys, strict=True):
        t = mre[key].traces[0]
        k = np.arange(1, len(t.measured) + 1)
        for j in range(len(t.sensor_ids)):
            on = t.measured[:, j]
            hit = on & t.detected[:, j]
            ax.plot(k[hit], np.full(hit.sum(), j + 1), "|", ms=9, color=f"C{j}")
            miss = on & ~t.detected[:, j]
            ax.plot(k[miss], np.full(miss.sum(), j + 1), "x", ms=5, color="r")
        ax.set_yticks(range(1, len(t.sensor_ids) + 1), t.sensor_ids)
        ax.set_ylim(0.5, len(t.sensor_ids) + 0.5)
        ax.set_ylabel(key, rotation=0, ha="right", fontsize="small")
    axes[-1, 0].set_xlabel("t (s); x = missed detection")
    return fig


def _fig_det_pos(mre: dict[str, CaseResult], keys: Sequence[str]):
    """Fig. 9 / 12: det_pos over time, mean over runs."""
    keys = [c for c in keys if c in mre]
    if not keys:
        return None
    fig, ax = figure_axes((7, 4))
    for key in keys:
        r = mre[key]
        ax.semilogy(np.arange(1, r.det_t.shape[1] + 1), r.det_t.mean(axis=0), label=key)
    ax.set(xlabel="t (s)", ylabel="det(P_k|k)_pos (m^4), mean over runs")
    ax.legend()
    return fig


def _fig_bound(checks: list[BoundCheck]):
    """Pd < 1: the MRE against the mean EKF covariance."""
    if not checks:
        return None
    fig, ax = figure_axes((7, 4))
    for i, c in enumerate(checks):
        k = np.arange(1, len(c.mre_det_t) + 1)
        ax.semilogy(k, c.mre_det_t, "--", color=f"C{i}", label=f"{c.case}: MRE (eq. 23)")
        ax.semilogy(k, c.filter_det_t, "-", color=f"C{i}", label=f"{c.case}: mean EKF P_k|k")
    ax.set(xlabel="t (s)", ylabel="det_pos (m^4)", title="Pd < 1: MRE bound vs filter")
    ax.legend(fontsize="small")
    return fig


def save_figures(res: RamdarasResults, out: str | Path) -> list[Path]:
    """Fig. 7/10 (tracks and sensor paths), 8/11 (selection timelines), 9/12 (det_pos) and
    the Pd < 1 bound check as PNG files in ``out``; returns the files."""
    mre = res.mre()
    figures = (
        ("fig10_tracks_sensor_paths.png", lambda: _fig_tracks(mre)),
        ("fig8_11_selection_timelines.png", lambda: _fig_timelines(mre)),
        ("fig9_det_pos_case1.png", lambda: _fig_det_pos(mre, CASE1_CASES)),
        ("fig12_det_pos_cases.png", lambda: _fig_det_pos(mre, FIG12_CASES)),
        ("pd_bound_vs_filter.png", lambda: _fig_bound(res.checks)),
    )
    return write_figures(figures, out, dpi=110, tight_layout=False, bbox_inches="tight")


def _options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="3 runs, fewer baselines")
    parser.add_argument("--cases", help="comma-separated case keys (default: all)")
    parser.add_argument("--scenarios", help="directory with ramdaras_*.yaml")


def _check_cli(args: argparse.Namespace) -> None:
    """Adds ``case_keys``, the cases of ``--cases``."""
    cases = None if args.cases is None else [c.strip() for c in args.cases.split(",")]
    args.case_keys = list(_case_keys(cases, "--cases"))


REPRODUCTION = Reproduction(
    "ramdaras",
    "Reproduce Ramdaras et al. (2010) sec. 5-6: MRE sensor selection and "
    "positioning, Cases 1-3 and Pd < 1 variants.",
    RunsOption(1, None, "Monte Carlo runs per case (20; 3 with --quick)"),
    options=_options,
    check=_check_cli,
    arguments=lambda args: dict(
        quick=args.quick, cases=args.case_keys, scenarios_dir=args.scenarios
    ),
    document=lambda res, figures, wall_time_s: res.to_json(figures, wall_time_s),
)
main = REPRODUCTION.main


if __name__ == "__main__":
    raise SystemExit(main())
