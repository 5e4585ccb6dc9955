"""Monte Carlo runs of a scenario and their summary (docs/api.md): ``run_batch`` runs and
evaluates each run on its worker, :func:`summarize` combines them.

One vocabulary for errors (README "Errors and bounds"): ``rmse_x_t[n][k]`` is the RMS over the
runs in which target n was held at epoch k of its x error; ``time_avg_rmse_x[n]`` its mean over
epochs 1..K (Hernandez' Table 1). ``bound_x_t[n][k]`` is the root of the mean over runs of the
PCRLB's x variance, ``time_avg_bound_x[n]`` its mean over epochs. GOSPA is averaged over epochs
and runs (``mean_gospa``).
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from activetrack.closed_loop.components import component_rngs
from activetrack.closed_loop.evaluation import RunEvaluation, evaluate_run
from activetrack.closed_loop.loop import run_once
from activetrack.closed_loop.record import RunRecord
from activetrack.filters.registry import filter_kind
from activetrack.kernels import expect_particle_work
from activetrack.montecarlo import Progress, Scheduler, parallel_map
from activetrack.scenarios.schema import Scenario

__all__ = ["BatchSummary", "run_batch", "summarize"]


def _nan_mean(values: np.ndarray, axis: int = 0) -> np.ndarray:
    """Mean over ``axis`` ignoring NaN (NaN where every entry is)."""
    with np.errstate(invalid="ignore"):
        count = np.sum(~np.isnan(values), axis=axis)
        return np.where(count > 0, np.nansum(values, axis=axis) / np.maximum(count, 1), math.nan)


def _nan_rms(values: np.ndarray, axis: int = 0) -> np.ndarray:
    return np.sqrt(_nan_mean(values**2, axis))


def _floats(values: np.ndarray) -> list:
    return np.asarray(values, dtype=float).tolist()


@dataclass
class BatchSummary:
    """``runs`` runs of one scenario (N targets, K epochs; the error vocabulary: module
    docstring): per target ``(N,)`` / ``(N, K)``, over the scene ``(K,)``, per run ``(R,)``."""

    scenario: str
    runs: int
    steps: int
    dt: float
    association: str
    target_ids: tuple[str, ...]
    time_avg_rmse_x: list[float]
    time_avg_rmse_y: list[float]
    time_avg_bound_x: list[float]
    time_avg_bound_y: list[float]
    rmse_x_t: list[list[float]]
    rmse_y_t: list[list[float]]
    bound_x_t: list[list[float]]
    bound_y_t: list[list[float]]
    held_fraction: list[float]
    mean_gospa: float
    gospa_t: list[float]
    localisation_t: list[float]
    missed_t: list[float]
    false_t: list[float]
    ospa_t: list[float]
    breaks: float
    swaps: float
    run_gospa: list[float]
    clamps: int
    evaluations_per_decision: float
    decision_time_s: float
    wall_time_s: float
    records: list[RunRecord] = field(default_factory=list, repr=False)
    evaluations: list[RunEvaluation] = field(default_factory=list, repr=False)

    def to_json(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k not in ("records", "evaluations")}

    @property
    def time(self) -> np.ndarray:
        """Epoch times t_1..t_K (K,) [s] of the per-epoch series."""
        return self.dt * np.arange(1, self.steps + 1)

    @property
    def rmse_t(self) -> np.ndarray:
        """RMSE over runs per target and epoch, ``(N, K, 2)`` [m] in x and y."""
        return np.stack([np.array(self.rmse_x_t), np.array(self.rmse_y_t)], axis=-1)

    @property
    def bound_t(self) -> np.ndarray:
        """The PCRLB per target and epoch, ``(N, K, 2)`` [m] in x and y."""
        return np.stack([np.array(self.bound_x_t), np.array(self.bound_y_t)], axis=-1)

    def table(self) -> list[dict[str, float | int | str]]:
        """A tidy table: one row per target and epoch (``pandas.DataFrame(s.table())``)."""
        rows: list[dict[str, float | int | str]] = []
        for n, target in enumerate(self.target_ids):
            for k in range(self.steps):
                rows.append(
                    {
                        "scenario": self.scenario,
                        "target": target,
                        "epoch": k + 1,
                        "time_s": float(self.time[k]),
                        "rmse_x_m": self.rmse_x_t[n][k],
                        "rmse_y_m": self.rmse_y_t[n][k],
                        "bound_x_m": self.bound_x_t[n][k],
                        "bound_y_m": self.bound_y_t[n][k],
                        "gospa_m": self.gospa_t[k],
                    }
                )
        return rows

    def run_table(self) -> list[dict[str, float | int | str]]:
        """A tidy table of the runs: one row per run, target and epoch 1..K, with the target's
        true position and its estimate (the holding track's; NaN where none holds it)."""
        rows: list[dict[str, float | int | str]] = []
        for r, (rec, ev) in enumerate(zip(self.records, self.evaluations, strict=True)):
            truth = np.asarray(rec.truth)[1:]
            for n, target in enumerate(self.target_ids):
                for k in range(self.steps):
                    est = truth[k, n] + ev.error[k, n]
                    rows.append(
                        {
                            "scenario": self.scenario,
                            "run": r,
                            "target": target,
                            "epoch": k + 1,
                            "time_s": float(self.time[k]),
                            "x_m": float(truth[k, n, 0]),
                            "y_m": float(truth[k, n, 2]),
                            "x_hat_m": float(est[0]),
                            "y_hat_m": float(est[2]),
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


def _run_task(task: tuple[Scenario, int | None]) -> tuple[RunRecord, RunEvaluation]:
    """One run and its evaluation (the evaluator generator of the run), both on the worker:
    the parent only adds up."""
    scenario, run = task
    record = run_once(scenario, run)
    return record, evaluate_run(scenario, record, component_rngs(scenario.seed, run)[3])


def run_batch(
    scenario: Scenario,
    runs: int = 1,
    jobs: int = 1,
    progress: Progress | None = None,
    scheduler: Scheduler | None = None,
    keep_records: bool = True,
) -> BatchSummary:
    """``runs`` seeded closed-loop runs on ``jobs`` worker processes or the Dask cluster
    ``scheduler`` (:func:`activetrack.montecarlo.parallel_map`, ``progress`` too), summarised
    by :func:`summarize`. Run r draws from its own generators (:func:`component_rngs`), so the
    result is the same for every ``jobs`` and backend."""
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ValueError(f"runs: must be an integer >= 1, got {runs!r}")
    start = time.perf_counter()
    tasks = [(scenario, r if runs > 1 else None) for r in range(runs)]
    if filter_kind(scenario.tracker.filter).particle_based:  # kernels loaded before the fork
        expect_particle_work(runs * scenario.steps * scenario.tracker.particles)
    results = parallel_map(_run_task, tasks, jobs, progress, scheduler)
    summary = summarize(
        scenario,
        [record for record, _ in results],
        [ev for _, ev in results],
        time.perf_counter() - start,
    )
    if not keep_records:
        summary.records, summary.evaluations = [], []
    return summary


def summarize(
    scenario: Scenario,
    records: list[RunRecord],
    evaluations: list[RunEvaluation] | None = None,
    wall_time_s: float = 0.0,
) -> BatchSummary:
    """The summary of runs of ``scenario`` (module docstring); ``evaluations`` computed here
    with each run's evaluator generator unless given."""
    runs = len(records)
    if evaluations is None:
        evaluations = [
            evaluate_run(scenario, rec, component_rngs(scenario.seed, None if runs == 1 else r)[3])
            for r, rec in enumerate(records)
        ]
    err = np.stack([ev.error for ev in evaluations])  # (R, K, N, 4)
    var = np.stack([ev.bound for ev in evaluations])[..., [0, 2], [0, 2]]  # (R, K, N, 2)
    rmse_x_t = _nan_rms(err[..., 0]).T  # (N, K)
    rmse_y_t = _nan_rms(err[..., 2]).T
    bound_x_t = np.sqrt(_nan_mean(var[..., 0])).T
    bound_y_t = np.sqrt(_nan_mean(var[..., 1])).T
    decisions = sum(len(r.decisions) for r in records)

    def series(name: str) -> list[float]:
        return _floats(np.mean([getattr(ev, name) for ev in evaluations], axis=0))

    run_gospa = [ev.mean_gospa for ev in evaluations]
    return BatchSummary(
        scenario=scenario.name,
        runs=runs,
        steps=scenario.steps,
        dt=scenario.dt,
        association="known" if scenario.known_association else "jpda",
        target_ids=tuple(records[0].target_ids),
        time_avg_rmse_x=_floats(_nan_mean(rmse_x_t, axis=1)),
        time_avg_rmse_y=_floats(_nan_mean(rmse_y_t, axis=1)),
        time_avg_bound_x=_floats(_nan_mean(bound_x_t, axis=1)),
        time_avg_bound_y=_floats(_nan_mean(bound_y_t, axis=1)),
        rmse_x_t=_floats(rmse_x_t),
        rmse_y_t=_floats(rmse_y_t),
        bound_x_t=_floats(bound_x_t),
        bound_y_t=_floats(bound_y_t),
        held_fraction=_floats(_nan_mean(np.stack([ev.held_fraction for ev in evaluations]))),
        mean_gospa=float(np.mean(run_gospa)),
        gospa_t=series("gospa"),
        localisation_t=series("localisation"),
        missed_t=series("missed"),
        false_t=series("false"),
        ospa_t=series("ospa"),
        breaks=float(np.mean([ev.breaks for ev in evaluations])),
        swaps=float(np.mean([ev.swaps for ev in evaluations])),
        run_gospa=[float(g) for g in run_gospa],
        clamps=sum(r.clamps for r in records),
        evaluations_per_decision=sum(r.evaluations for r in records) / max(decisions, 1),
        decision_time_s=sum(r.planning_time_s for r in records) / max(decisions, 1),
        wall_time_s=wall_time_s,
        records=records,
        evaluations=evaluations,
    )
