"""The multi-target closed loop without ROS, and its Monte Carlo batches.

``run_multi_once`` is the reference the ROS graph reproduces in lockstep mode, as
:func:`activetrack.closed_loop.batch.run_once` is for one target; the generators are the same
(:func:`activetrack.closed_loop.batch.component_rngs`: simulator, tracker, planner, evaluator).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from activetrack.closed_loop.batch import component_rngs
from activetrack.closed_loop.data import PlatformSnapshot
from activetrack.montecarlo import Progress, Scheduler, parallel_map
from activetrack.multitarget.data import MultiDecision, MultiRunRecord, TrackSet
from activetrack.multitarget.evaluation import RunEvaluation, evaluate_run
from activetrack.multitarget.planner import MultiTargetPlanner
from activetrack.multitarget.simulator import MultiTargetSimulator
from activetrack.multitarget.tracker import MultiTargetTracker
from activetrack.scenarios.schema import Scenario

__all__ = ["MultiBatchSummary", "MultiPlanner", "run_multi_batch", "run_multi_once"]


class MultiPlanner(Protocol):
    """What the loop asks of a planner (:class:`MultiTargetPlanner`, or another one to compare
    against: the benchmarks' Stone Soup sensor manager)."""

    def decide(
        self, epoch: int, tracks: TrackSet, platforms: Sequence[PlatformSnapshot]
    ) -> MultiDecision: ...


PlannerFactory = Callable[[Scenario, np.random.Generator], MultiPlanner]


def run_multi_once(
    scenario: Scenario, run: int | None = None, planner_factory: PlannerFactory | None = None
) -> MultiRunRecord:
    """One multi-target closed-loop run with the generators of (seed, run); the planner is
    ``planner_factory(scenario, planner_rng)`` (default :class:`MultiTargetPlanner`)."""
    sim_rng, trk_rng, plan_rng, _ = component_rngs(scenario.seed, run)
    start = time.perf_counter()
    sim = MultiTargetSimulator(scenario, sim_rng)
    tracker = MultiTargetTracker(scenario, trk_rng)
    planner = (planner_factory or MultiTargetPlanner)(scenario, plan_rng)
    platform_ids = tuple(sim.platforms)
    tracks = tracker.snapshot()
    truth = [sim.truth_array()]
    track_sets: list[TrackSet] = [tracks]
    paths = [np.stack([sim.platforms[i].pv for i in platform_ids])]
    record = MultiRunRecord(
        target_ids=sim.target_ids,
        sensor_ids=tuple(sim.scan_sensors),
        platform_ids=platform_ids,
        truth=np.empty(0),
        tracks=track_sets,
        platform_paths=np.empty(0),
    )
    observed = []
    for k in range(scenario.steps + 1):
        if k > 0:
            scans = sim.advance()
            tracks = tracker.step(k, sim.time, scans)
            record.scans.append(scans)
            record.scan_truth.append(sim.last_truth)
            observed.append(sim.last_observed)
            truth.append(sim.truth_array())
            track_sets.append(tracks)
            paths.append(np.stack([sim.platforms[i].pv for i in platform_ids]))
        if k < scenario.steps:
            decision = planner.decide(k, tracks, sim.platform_snapshots())
            _apply(sim, decision, record)
    record.truth = np.array(truth)
    record.platform_paths = np.array(paths)
    record.observed = np.array(observed, dtype=bool).reshape(
        scenario.steps, len(record.sensor_ids), len(record.target_ids)
    )
    record.wall_time_s = time.perf_counter() - start
    return record


def _apply(sim: MultiTargetSimulator, decision: MultiDecision, record: MultiRunRecord) -> None:
    record.decisions.append(decision)
    if decision.report is not None:
        record.planning_time_s += decision.report.wall_time_s
    for cmd in decision.commands:
        record.clamps += sim.apply_command(cmd).clamped
    for beam in decision.beams:
        sim.apply_beam(beam)


@dataclass
class MultiBatchSummary:
    """Monte Carlo runs of one multi-target scenario: the mean GOSPA over time and over runs,
    track breaks and swaps, each target's RMSE against its bound (runs averaged)."""

    scenario: str
    runs: int
    steps: int
    dt: float
    mean_gospa: float  # time and run average
    gospa_t: list[float]  # (K,) run average per epoch
    localisation_t: list[float]
    missed_t: list[float]
    false_t: list[float]
    breaks: float  # per run
    swaps: float
    target_ids: tuple[str, ...]
    target_rmse: list[float]  # (N,) RMS over runs
    target_bound: list[float]
    held_fraction: list[float]
    clamps: int
    wall_time_s: float
    run_gospa: list[float] = field(default_factory=list)  # (R,) each run's time average
    records: list[MultiRunRecord] = field(default_factory=list, repr=False)
    evaluations: list[RunEvaluation] = field(default_factory=list, repr=False)

    def to_json(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k not in ("records", "evaluations")}

    def table(self) -> list[dict[str, float | int | str]]:
        """One row per epoch: GOSPA and its split, run averages."""
        return [
            {
                "scenario": self.scenario,
                "epoch": k + 1,
                "time_s": self.dt * (k + 1),
                "gospa_m": self.gospa_t[k],
                "localisation_m": self.localisation_t[k],
                "missed_m": self.missed_t[k],
                "false_m": self.false_t[k],
            }
            for k in range(self.steps)
        ]


def _run_task(task: tuple[Scenario, int | None]) -> tuple[MultiRunRecord, RunEvaluation]:
    scenario, run = task
    record = run_multi_once(scenario, run)
    evaluation = evaluate_run(scenario, record, component_rngs(scenario.seed, run)[3])
    return record, evaluation


def run_multi_batch(
    scenario: Scenario,
    runs: int = 1,
    jobs: int = 1,
    progress: Progress | None = None,
    keep_records: bool = True,
    scheduler: Scheduler | None = None,
) -> MultiBatchSummary:
    """``runs`` seeded multi-target runs on ``jobs`` worker processes, or on the workers of the
    Dask cluster ``scheduler`` (the same result for every ``jobs`` and backend), each evaluated
    (:func:`evaluate_run`) with its evaluator generator."""
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ValueError(f"runs: must be an integer >= 1, got {runs!r}")
    start = time.perf_counter()
    tasks = [(scenario, r if runs > 1 else None) for r in range(runs)]
    results = parallel_map(_run_task, tasks, jobs, progress, scheduler)
    records = [r for r, _ in results]
    evals = [e for _, e in results]
    summary = summarize_multi(scenario, records, evals, time.perf_counter() - start)
    if not keep_records:
        summary.records = []
    return summary


def _rms(values: np.ndarray) -> list[float]:
    """Root mean square over runs of per-run RMS figures, ignoring NaN (a target never held)."""
    with np.errstate(invalid="ignore"):
        out = np.sqrt(np.nanmean(values**2, axis=0)) if np.any(np.isfinite(values)) else values[0]
    return [float(v) for v in out]


def summarize_multi(
    scenario: Scenario,
    records: list[MultiRunRecord],
    evals: list[RunEvaluation],
    wall_time_s: float,
) -> MultiBatchSummary:
    def mean_t(name: str) -> list[float]:
        return [float(v) for v in np.mean([getattr(e, name) for e in evals], axis=0)]

    run_gospa = [e.mean_gospa for e in evals]
    return MultiBatchSummary(
        scenario=scenario.name,
        runs=len(records),
        steps=scenario.steps,
        dt=scenario.dt,
        mean_gospa=float(np.mean(run_gospa)),
        gospa_t=mean_t("gospa"),
        localisation_t=mean_t("localisation"),
        missed_t=mean_t("missed"),
        false_t=mean_t("false"),
        breaks=float(np.mean([e.breaks for e in evals])),
        swaps=float(np.mean([e.swaps for e in evals])),
        target_ids=records[0].target_ids,
        target_rmse=_rms(np.array([e.target_rmse for e in evals])),
        target_bound=_rms(np.array([e.target_bound for e in evals])),
        held_fraction=mean_t("held_fraction"),
        clamps=sum(r.clamps for r in records),
        wall_time_s=wall_time_s,
        run_gospa=[float(g) for g in run_gospa],
        records=records,
        evaluations=evals,
    )
