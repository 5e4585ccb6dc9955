"""Reproduce Vander Hook, Tokekar, Isler (003): Table I, Fig. 5 and the sec. V worked example.

Table I: C = E[T_ALG] / E[T_LB] for sweeps of r0_hat, c_d, t_m and beta, T_ALG = N t_m + distance
from the batched simulation (``vanderhook_sim``), T_LB from Theorem 2 (eq. 6) at the true range;
the upper bound is Theorem 1 (eq. 5) with N and the travel of ``cautious_schedule``, next to the
printed closed forms (Lemma 4, eq. 4). The simulated ratio uses the one-sided sigma_beta, which
reproduces the paper's numbers; the printed two-sided one is shown alongside (docs/vanderhook.md).
Fig. 5: measurements and final error against beta, with the greedy baseline, and the wrong-side
(ambiguity failure) rates. Every batch of localisations is one task of a single parallel map.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from activetrack.argtypes import int_in_range
from activetrack.checks import require_int
from activetrack.limits import MAX_RUNS, MAX_SEED
from activetrack.models.sensors import AmbiguousBearingSensor
from activetrack.montecarlo import Progress, Scheduler, TaskProgress, check_jobs, parallel_map
from activetrack.planning.cautious import CautiousPlanner, caution_gamma
from activetrack.planning.cautious_bounds import (
    cautious_schedule,
    distance_bound,
    lemma4_measurements,
    time_lower_bound,
    time_upper_bound,
)
from activetrack.plots import write_figures
from activetrack_experiments.reproduction import Reproduction, RunsOption, figure_axes, split
from activetrack_experiments.vanderhook_sim import (
    SIGMA_S_DEFAULT,
    LocalisationBatch,
    simulate_localisation,
)

SIGMA0 = 60.0  # m, Table I prior
R_MIN = 1.0  # m, floor under the cautious range (reached only when sigma_beta is infinite)
GREEDY_RANGE = 10.0  # m, fixed standoff of the non-cautious baseline
BASE = {"r0_hat": 100.0, "c_d": 0.1, "t_m": 60.0, "beta": 0.1}
BETAS = (0.001, 0.01, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5)  # Fig. 5
QUICK_BETAS = (0.01, 0.1, 0.5)
TWO_SIDED_BETAS = (0.01, 0.1)  # the failure rows repeated with the printed sigma_beta
# Sec. V worked example: sigma_0 (m), r_0 (m), t_m (s), c_d (one sigma to < 6 m).
EXAMPLE = {"sigma0": 50.0, "r0_hat": 60.0, "t_m": 60.0, "c_d": 6.0 / 50.0}

# Table I of the paper: (sweep, value) -> (simulated ratio, theoretical upper bound).
PAPER_TABLE1 = {
    ("r0_hat", 20.0): (3.6366, 7.2853),
    ("r0_hat", 50.0): (2.8853, 5.4477),
    ("r0_hat", 200.0): (1.6651, 2.5477),
    ("c_d", 0.25): (1.3862, 2.2164),
    ("c_d", 0.1): (2.1418, 3.5869),
    ("c_d", 0.01): (2.8044, 4.9432),
    ("t_m", 20.0): (1.6046, 2.3268),
    ("t_m", 60.0): (2.1398, 3.5869),
    ("t_m", 110.0): (2.5568, 4.5461),
    ("beta", 0.1): (2.6450, 3.9104),
    ("beta", 0.2): (2.5699, 3.8353),
    ("beta", 0.5): (1.5946, 2.2264),
}


@dataclass(frozen=True)
class SimTask:
    """One batch: ``simulate_localisation(runs, default_rng(seed), **options)``."""

    runs: int
    seed: int
    options: tuple[tuple[str, Any], ...]

    @classmethod
    def of(cls, runs: int, seed: int, **options) -> SimTask:
        return cls(int(runs), int(seed), tuple(sorted(options.items())))


def simulate_task(task: SimTask) -> LocalisationBatch:
    """Run one :class:`SimTask` (the function of the parallel map)."""
    return simulate_localisation(task.runs, np.random.default_rng(task.seed), **dict(task.options))


def simulate_all(
    tasks: Sequence[SimTask],
    jobs: int = 1,
    progress: Progress | None = None,
    scheduler: Scheduler | None = None,
) -> list[LocalisationBatch]:
    """The batches of ``tasks`` in task order, equal tasks run once (one parallel map;
    ``progress`` counts the distinct tasks done)."""
    unique = list(dict.fromkeys(tasks))
    batches = parallel_map(simulate_task, unique, jobs, progress, scheduler)
    done = dict(zip(unique, batches, strict=True))
    return [done[t] for t in tasks]


@dataclass(frozen=True)
class Table1Row:
    sweep: str
    value: float
    simulated_ratio: float  # one-sided sigma_beta (reproduces the paper)
    upper_bound: float  # Theorem 1 / E[T_LB], N and travel from cautious_schedule
    closed_form_upper_bound: float | None  # Lemma 4 + eq. 4 as printed (None: gamma infinite)
    simulated_ratio_two_sided: float  # printed sigma_beta formula
    paper_ratio: float
    paper_upper_bound: float
    n_measurements: float
    distance: float
    mean_t_lb: float

    @property
    def deviation(self) -> float:
        """Relative deviation of the simulated ratio from the paper's."""
        return self.simulated_ratio / self.paper_ratio - 1.0


def _params(sweep: str, value: float) -> dict:
    return dict(BASE, **{sweep: value})


def _table1_tasks(runs: int, seed: int) -> list[SimTask]:
    """Two batches per row (one-sided, two-sided tail), common random numbers."""
    tasks = []
    for sweep, value in PAPER_TABLE1:
        kw = dict(sigma0=SIGMA0, **_params(sweep, value))
        tasks += [
            SimTask.of(runs, seed, r_min=R_MIN, tail=t, **kw) for t in ("one_sided", "two_sided")
        ]
    return tasks


def _ratio_and_bound(batch: LocalisationBatch, params, tail):
    t_lb = time_lower_bound(batch.r0_true, SIGMA0, params["t_m"], params["c_d"], SIGMA_S_DEFAULT)
    ratio = float(batch.time.mean() / t_lb.mean())
    sched = cautious_schedule(
        SIGMA0**2 * np.eye(2), params["beta"], SIGMA_S_DEFAULT, params["c_d"], tail, R_MIN
    )
    d01 = float(batch.first_leg[0])  # the same for every run: the prior is shared
    t_alg = time_upper_bound(sched.n_measurements, params["t_m"], sched.travel_bound(d01))
    return ratio, float(t_alg / t_lb.mean()), float(t_lb.mean()), d01


def _closed_form_bound(params, d01: float, mean_t_lb: float) -> float | None:
    """Lemma 4 + eq. 4 as printed over E[T_LB] (None when sigma_beta is infinite)."""
    beta, c_d = params["beta"], params["c_d"]
    if not math.isfinite(caution_gamma(beta, SIGMA_S_DEFAULT, "one_sided")):
        return None
    n_z = lemma4_measurements(beta, SIGMA_S_DEFAULT, c_d, "one_sided")
    d_a = distance_bound(SIGMA0, beta, SIGMA_S_DEFAULT, c_d, d01, "one_sided")
    return float(time_upper_bound(n_z, params["t_m"], d_a) / mean_t_lb)


def _table1_rows(batches: Sequence[LocalisationBatch]) -> list[Table1Row]:
    rows = []
    for i, ((sweep, value), (paper_ratio, paper_ub)) in enumerate(PAPER_TABLE1.items()):
        params = _params(sweep, value)
        one, two = batches[2 * i], batches[2 * i + 1]
        ratio, ub, mean_t_lb, d01 = _ratio_and_bound(one, params, "one_sided")
        ratio_two, _, _, _ = _ratio_and_bound(two, params, "two_sided")
        rows.append(
            Table1Row(
                sweep=sweep,
                value=float(value),
                simulated_ratio=ratio,
                upper_bound=ub,
                closed_form_upper_bound=_closed_form_bound(params, d01, mean_t_lb),
                simulated_ratio_two_sided=ratio_two,
                paper_ratio=paper_ratio,
                paper_upper_bound=paper_ub,
                n_measurements=float(one.n_measurements.mean()),
                distance=float(one.distance.mean()),
                mean_t_lb=mean_t_lb,
            )
        )
    return rows


def table1(
    runs: int, seed: int = 0, jobs: int = 1, scheduler: Scheduler | None = None
) -> list[Table1Row]:
    """Table I: one batch of ``runs`` localisations per (sweep, value), common random numbers."""
    return _table1_rows(simulate_all(_table1_tasks(runs, seed), jobs, scheduler=scheduler))


@dataclass(frozen=True)
class WorkedExample:
    """Sec. V: sigma_0 = 50 m, r_0 = 60 m, t_m = 60 s, sigma_s = 15 deg, one-sigma to < 6 m."""

    n_measurements: int  # Lemma 4, printed sigma_beta (the paper's computation)
    n_schedule: int  # Algorithm 1 run on the covariance
    n_simulated: float  # mean over simulated runs
    travel_closed_form: float  # D_A, eq. 4 (m)
    travel_bound: float  # Lemma 5's argument summed exactly (m)
    t_alg_bound: float  # eq. 5 with Lemma 4's N_z and eq. 4 (s)
    t_lb: float  # eq. 6 at r_0 (s)
    ratio_bound: float  # t_alg_bound / t_lb
    final_std: float  # larger posterior standard deviation (m)


def _example_task(runs: int, seed: int, beta: float) -> SimTask:
    return SimTask.of(runs, seed, beta=beta, r_min=R_MIN, **EXAMPLE)


def _worked_example(batch: LocalisationBatch, beta: float) -> WorkedExample:
    sigma0, r0, t_m, c_d = EXAMPLE["sigma0"], EXAMPLE["r0_hat"], EXAMPLE["t_m"], EXAMPLE["c_d"]
    n_z = lemma4_measurements(beta, SIGMA_S_DEFAULT, c_d)
    sched = cautious_schedule(sigma0**2 * np.eye(2), beta, SIGMA_S_DEFAULT, c_d)
    d01 = float(batch.first_leg[0])
    d_a = float(distance_bound(sigma0, beta, SIGMA_S_DEFAULT, c_d, d01))
    t_alg = float(time_upper_bound(n_z, t_m, d_a))
    t_lb = float(time_lower_bound(r0, sigma0, t_m, c_d, SIGMA_S_DEFAULT))
    return WorkedExample(
        n_measurements=n_z,
        n_schedule=sched.n_measurements,
        n_simulated=float(batch.n_measurements.mean()),
        travel_closed_form=d_a,
        travel_bound=float(sched.travel_bound(d01)),
        t_alg_bound=t_alg,
        t_lb=t_lb,
        ratio_bound=t_alg / t_lb,
        final_std=float(np.sqrt(sched.variances[0])),
    )


def worked_example(runs: int = 500, seed: int = 0, beta: float = 0.1) -> WorkedExample:
    return _worked_example(simulate_task(_example_task(runs, seed, beta)), beta)


@dataclass(frozen=True)
class FailureRow:
    """Ambiguity failures of one strategy at the Table I base setting."""

    strategy: str
    beta: float | None
    final_wrong_side_rate: float  # fraction of runs ending with x_hat on the wrong side
    wrong_side_rate: float  # fraction of runs with >= 1 wrong-side measurement
    first_wrong_side_rate: float  # fraction of runs whose first measurement was wrong-side
    events_per_run: float
    n_measurements: float
    median_error: float  # m
    mean_error: float  # m
    mean_time: float  # s


def _failure_tasks(runs: int, betas, seed: int, tail: str) -> list[SimTask]:
    """Per beta and for the greedy baseline: the full run and its first measurement only
    (same true targets and noise stream per row)."""
    common = dict(sigma0=SIGMA0, r0_hat=BASE["r0_hat"], c_d=BASE["c_d"], t_m=BASE["t_m"])
    options = [dict(beta=beta, r_min=R_MIN, tail=tail, **common) for beta in betas]
    options.append(dict(strategy="greedy", greedy_range=GREEDY_RANGE, **common))
    return [
        SimTask.of(runs, seed, **extra, **kw)
        for kw in options
        for extra in ({}, {"max_measurements": 1})
    ]


def _failure_rows(betas, batches: Sequence[LocalisationBatch]) -> list[FailureRow]:
    """A row per beta and the greedy baseline from their (full run, first measurement) batches."""
    strategies = [("cautious", float(b)) for b in betas] + [("greedy", None)]
    return [
        FailureRow(
            strategy=strategy,
            beta=beta,
            final_wrong_side_rate=float(batch.final_wrong_side.mean()),
            wrong_side_rate=float(batch.wrong_side.mean()),
            first_wrong_side_rate=float(first.wrong_side.mean()),
            events_per_run=float(batch.wrong_side_events.mean()),
            n_measurements=float(batch.n_measurements.mean()),
            median_error=float(np.median(batch.final_error)),
            mean_error=float(batch.final_error.mean()),
            mean_time=float(batch.time.mean()),
        )
        for (strategy, beta), batch, first in zip(
            strategies, batches[::2], batches[1::2], strict=True
        )
    ]


@dataclass(frozen=True)
class ExampleRun:
    """One localisation: true target (2,), sensing locations (N, 2), estimates (N + 1, 2)."""

    truth: np.ndarray
    sensors: np.ndarray
    estimates: np.ndarray


def example_trajectory(seed: int = 1, beta: float = 0.1) -> ExampleRun:
    """One run driven through :class:`CautiousPlanner` (the ROS planner's API), like Fig. 4."""
    rng = np.random.default_rng(seed)
    P0 = SIGMA0**2 * np.eye(2)
    planner = CautiousPlanner(sigma_s=SIGMA_S_DEFAULT, prior_cov=P0, beta=beta, r_min=R_MIN)
    sensor = AmbiguousBearingSensor(sigma=SIGMA_S_DEFAULT)
    truth = SIGMA0 * rng.standard_normal(2)
    mean, cov, robot = np.zeros(2), P0, np.array([BASE["r0_hat"], 0.0])
    sensors, estimates = [], [mean]
    while not (action := planner.next_action(mean, cov, robot, len(sensors))).done:
        robot = action.waypoint
        z = sensor.sample([truth[0], 0, truth[1], 0], [robot[0], 0, robot[1], 0], rng)[0]
        upd = planner.update(mean, cov, z, robot)
        mean, cov = upd.mean, upd.cov
        sensors.append(robot)
        estimates.append(mean)
    return ExampleRun(truth, np.array(sensors), np.array(estimates))


@dataclass
class VanderHookResults:
    """What :func:`reproduce` computed."""

    runs: int
    seed: int
    example: WorkedExample
    table1: list[Table1Row]
    failures: list[FailureRow]  # one-sided sigma_beta (Fig. 5), greedy last
    failures_two_sided: list[FailureRow]
    trajectory: ExampleRun  # Fig. 4

    def table(self, section: str = "table1") -> list[dict]:
        """Flat rows for ``pandas.DataFrame``: ``"table1"`` (a row per sweep value, with the
        deviation from the paper) or ``"failures"`` (a row per strategy and beta, ``tail``
        says which sigma_beta; the greedy rows do not depend on it)."""
        if section == "table1":
            return [{**asdict(r), "deviation": r.deviation} for r in self.table1]
        if section == "failures":
            groups = (("one_sided", self.failures), ("two_sided", self.failures_two_sided))
            return [{"tail": tail, **asdict(f)} for tail, rows in groups for f in rows]
        raise ValueError(f"section must be 'table1' or 'failures', got {section!r}")

    def to_json(self) -> dict:
        """The document ``--json`` (and ``OUT/results.json``) holds."""
        return {
            "runs": self.runs,
            "seed": self.seed,
            "table1": [asdict(r) for r in self.table1],
            "worked_example": asdict(self.example),
            "n_measurements": self.example.n_measurements,
            "failures": [asdict(f) for f in self.failures],
            "failures_two_sided": [asdict(f) for f in self.failures_two_sided],
        }


def reproduce(
    runs: int | None = None,
    *,
    seed: int = 0,
    quick: bool = False,
    jobs: int = 1,
    scheduler: Scheduler | None = None,
    betas: Sequence[float] | None = None,
    task_progress: Callable[[int, int], None] | None = None,
) -> VanderHookResults:
    """Vander Hook et al. (003): the worked example (min(runs, 1000) runs), Table I and the
    Fig. 5 failure rows (``betas``, default ``BETAS``, ``QUICK_BETAS`` when ``quick``; and
    ``TWO_SIDED_BETAS`` with the two-sided sigma_beta), ``runs`` localisations per batch
    (default 4000, 400 when ``quick``), each batch from ``default_rng(seed)``, all batches in
    one parallel map. Fig. 4's single run always uses seed 1.
    """
    runs = (400 if quick else 4000) if runs is None else runs
    require_int("runs", runs, 1, MAX_RUNS)
    require_int("seed", seed, 0, MAX_SEED)
    check_jobs(jobs, scheduler)
    betas = tuple(betas) if betas is not None else QUICK_BETAS if quick else BETAS
    groups = [
        [_example_task(min(runs, 1000), seed, 0.1)],
        _table1_tasks(runs, seed),
        _failure_tasks(runs, betas, seed, "one_sided"),
        _failure_tasks(runs, TWO_SIDED_BETAS, seed, "two_sided"),
    ]
    every = [t for g in groups for t in g]
    tasks = TaskProgress(len(set(every)), task_progress)
    batches = simulate_all(every, jobs, tasks.of_map(), scheduler)
    ex, t1, fail, fail_two = split(batches, [len(g) for g in groups])
    return VanderHookResults(
        runs=runs,
        seed=seed,
        example=_worked_example(ex[0], 0.1),
        table1=_table1_rows(t1),
        failures=_failure_rows(betas, fail),
        failures_two_sided=_failure_rows(TWO_SIDED_BETAS, fail_two),
        trajectory=example_trajectory(),
    )


def format_table1(rows: list[Table1Row]) -> str:
    head = (
        f"{'sweep':7s} {'value':>6s} | {'sim C':>6s} {'paper':>6s} {'dev':>5s} | "
        f"{'UB':>6s} {'UB(4,eq4)':>9s} {'paperUB':>7s} | {'C 2-sided':>9s} {'N':>4s} {'D (m)':>6s}"
    )
    lines = ["Table I: C = E[T_ALG] / E[T_LB] (one-sided sigma_beta; see docs)", head]
    for r in rows:
        closed = f"{r.closed_form_upper_bound:9.3f}" if r.closed_form_upper_bound else "      n/a"
        lines.append(
            f"{r.sweep:7s} {r.value:6g} | {r.simulated_ratio:6.3f} {r.paper_ratio:6.3f} "
            f"{100 * r.deviation:+4.0f}% | {r.upper_bound:6.3f} {closed} "
            f"{r.paper_upper_bound:7.3f} | {r.simulated_ratio_two_sided:9.3f} "
            f"{r.n_measurements:4.1f} {r.distance:6.1f}"
        )
    return "\n".join(lines)


def format_failures(rows: list[FailureRow]) -> str:
    lines = [
        "Fig. 5 / ambiguity failures (r0_hat = 100 m, c_d = 0.1, t_m = 60 s)",
        f"{'strategy':9s} {'beta':>6s} {'ends wrong':>10s} {'any wrong':>9s} {'first':>6s} "
        f"{'N':>5s} {'median err':>10s} {'mean err':>8s} {'time (s)':>8s}",
    ]
    for r in rows:
        beta = f"{r.beta:6g}" if r.beta is not None else "     -"
        lines.append(
            f"{r.strategy:9s} {beta} {r.final_wrong_side_rate:10.3f} {r.wrong_side_rate:9.3f} "
            f"{r.first_wrong_side_rate:6.3f} "
            f"{r.n_measurements:5.2f} {r.median_error:10.1f} {r.mean_error:8.1f} "
            f"{r.mean_time:8.0f}"
        )
    return "\n".join(lines)


def format_example(ex: WorkedExample) -> str:
    return "\n".join(
        [
            "Worked example (sec. V): sigma_0 = 50 m, r_0 = 60 m, t_m = 60 s, sigma_s = 15 deg, "
            "beta = 0.1, c_d = 6/50",
            f"  N = {ex.n_measurements} (Lemma 4); Algorithm 1 takes {ex.n_schedule} "
            f"(simulated mean {ex.n_simulated:.2f}); final sigma(1) = {ex.final_std:.2f} m",
            f"  travel <= {ex.travel_closed_form:.0f} m (eq. 4), "
            f"<= {ex.travel_bound:.0f} m (exact sum); T_ALG <= {ex.t_alg_bound:.0f} s, "
            f"T_LB = {ex.t_lb:.0f} s, ratio <= {ex.ratio_bound:.2f}",
        ]
    )


def format_report(res: VanderHookResults) -> str:
    """Everything ``activetrack reproduce vanderhook`` prints before the list of plots."""
    two_sided = format_failures(res.failures_two_sided).splitlines()[2:]
    parts = [
        format_example(res.example),
        "",
        format_table1(res.table1),
        "",
        format_failures(res.failures),
        "(two-sided sigma_beta:)",
        *two_sided,
    ]
    return "\n".join(parts)


def _fig_beta(failures: list[FailureRow]):
    """Fig. 5: measurements and final error against beta, the greedy baseline dashed."""
    cautious = [f for f in failures if f.strategy == "cautious"]
    greedy = next(f for f in failures if f.strategy == "greedy")
    betas = [f.beta for f in cautious]
    fig, (ax1, ax2) = figure_axes((6, 6), 2, 1, sharex=True)
    ax1.semilogx(betas, [f.n_measurements for f in cautious], "o-", label="cautious")
    ax1.axhline(greedy.n_measurements, color="r", ls="--", label="greedy (10 m standoff)")
    ax1.set_ylabel("measurements")
    ax1.legend()
    ax2.semilogx(betas, [f.median_error for f in cautious], "o-", label="median")
    ax2.semilogx(betas, [f.mean_error for f in cautious], "s-", label="mean")
    ax2.axhline(greedy.median_error, color="r", ls="--", label="greedy median")
    ax2.set(xlabel="beta", ylabel="final error ||x_hat - x*|| (m)")
    ax2.legend()
    fig.suptitle("Vander Hook Fig. 5: effect of beta")
    return fig


def _fig_table1(rows: list[Table1Row]):
    """Table I: our ratios, the paper's and our bound, per sweep."""
    fig, ax = figure_axes((6, 4))
    sweeps = list(dict.fromkeys(r.sweep for r in rows))
    for i, sweep in enumerate(sweeps):
        sel = [r for r in rows if r.sweep == sweep]
        x = np.arange(len(sel)) + 4 * i
        ax.plot(x, [r.simulated_ratio for r in sel], "bo-", label="ours" if i == 0 else None)
        ax.plot(x, [r.paper_ratio for r in sel], "ks--", label="paper" if i == 0 else None)
        ax.plot(x, [r.upper_bound for r in sel], "r^:", label="our bound" if i == 0 else None)
        for xi, r in zip(x, sel, strict=True):
            ax.annotate(f"{r.value:g}", (xi, 0.2), ha="center", fontsize=7)
    ax.set_xticks([4 * i + 1 for i in range(len(sweeps))], sweeps)
    ax.set(ylabel="C = E[T_ALG] / E[T_LB]", ylim=(0, None), title="Vander Hook Table I")
    ax.legend()
    return fig


def _fig_run(run: ExampleRun):
    """Fig. 4: sensing locations and estimates of one cautious run."""
    fig, ax = figure_axes((5, 5))
    ax.plot(*np.vstack([[BASE["r0_hat"], 0.0], run.sensors]).T, "g.-", label="sensor locations")
    ax.plot(*run.estimates.T, "r.-", label="estimates")
    ax.plot(*run.truth, "k*", ms=12, label="true target")
    ax.set(aspect="equal", title="Vander Hook Fig. 4: one cautious run")
    ax.legend()
    return fig


def save_figures(res: VanderHookResults, out: str | Path) -> list[Path]:
    """``fig5_beta.png``, ``table1.png`` and ``fig4_run.png`` in ``out``; returns the files."""
    figures = (
        ("fig5_beta.png", lambda: _fig_beta(res.failures)),
        ("table1.png", lambda: _fig_table1(res.table1)),
        ("fig4_run.png", lambda: _fig_run(res.trajectory)),
    )
    return write_figures(figures, out, dpi=120)


def _options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="400 runs, fewer beta values")
    parser.add_argument(
        "--seed", type=int_in_range(0, MAX_SEED), default=0, help="seed of the draws (0)"
    )


def _quick_runs(args: argparse.Namespace) -> None:
    """``--quick`` runs 400 localisations per batch, whatever ``--runs`` says."""
    if args.quick:
        args.runs = None


REPRODUCTION = Reproduction(
    "vanderhook",
    __doc__.splitlines()[0],
    RunsOption(1, 4000, "Monte Carlo runs per row (4000)"),
    options=_options,
    check=_quick_runs,
    arguments=lambda args: dict(seed=args.seed, quick=args.quick),
)
main = REPRODUCTION.main


if __name__ == "__main__":
    raise SystemExit(main())
