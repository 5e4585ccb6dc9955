"""Multi-target active tracking in clutter: the planner against its baselines (issues 14, 25).

On each multi-target scenario, (a) ``mt_bearings_crossing``: two bearings-only platforms, three
crossing targets; (b) ``mt_radars_beams``: heterogeneous radars with beams, five targets; (c)
``mt_appear_disappear``: targets born and dying, tracks started from detections; (d)
``mt_search_track``: one radar beam that must search for targets entering across the region's
edges and track those it found; (e) ``mt_mixed_platforms``: bearings-only platforms and a radar,
each with a beam, over crossing targets; ``runs`` seeded closed-loop runs of each strategy on
common random numbers (run r of every strategy is the same world: target motion, each sensor's
detections, noise and clutter draw from their own streams, :mod:`activetrack.simulation.streams`):

- ``planner``: the scenario as written (manoeuvres against every track, beams by its
  ``planner.targets`` objective and assignment);
- ``hold_course``: the platforms hold course and speed, beams assigned by MRE on
  ``planner.criterion`` (``objective: criterion`` whatever the file sets: the baseline stays
  the one it was);
- ``random_assignment``: the planner's manoeuvres, but beams pointed at uniformly drawn tracks;
- ``stonesoup_manager`` on (b) and (d) when Stone Soup is installed (``make bench``): Stone
  Soup's ``BruteForceSensorManager`` with its ``UncertaintyRewardFunction`` points the beams,
  the platforms hold course (:mod:`activetrack_experiments.stonesoup_manager`).

The figure of merit is the time-averaged GOSPA (cut-off and order from the scenario's
``evaluation``), averaged over runs, with its Monte Carlo standard error; the improvement is
``1 - GOSPA(planner) / GOSPA(baseline)`` (the issue asks, per scene, :data:`MARGINS` below
the better baseline with both paired intervals below zero; the report says which scenes meet
it). The paired
difference GOSPA(planner) - GOSPA(baseline), run by run, has a 95 % Student-t interval
(:func:`activetrack.montecarlo.paired.paired_difference`); the report's last line is
``planner_gain_vs_best_baseline_pct=a:<x>,b:<x>,c:<x>,d:<x>,e:<x>``: the planner's GOSPA below
the better of hold course and random beams, in percent, per scenario.
"""

from __future__ import annotations

import argparse
import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from activetrack.closed_loop.batch import BatchSummary, run_batch, summarize
from activetrack.closed_loop.components import component_rngs
from activetrack.closed_loop.evaluation import RunEvaluation, evaluate_run
from activetrack.closed_loop.loop import run_once
from activetrack.closed_loop.record import RunRecord
from activetrack.montecarlo import Scheduler, TaskProgress, check_jobs, parallel_map
from activetrack.montecarlo.dask import connected
from activetrack.montecarlo.paired import PairedDifference, paired_difference
from activetrack.plots import write_figures
from activetrack.scenarios import load_scenario, with_changes
from activetrack.scenarios.schema import Scenario
from activetrack_experiments import stonesoup_manager
from activetrack_experiments.paths import scenario_path
from activetrack_experiments.reproduction import Reproduction, RunsOption, figure_axes

__all__ = [
    "MANAGER",
    "MARGINS",
    "SCENARIOS",
    "STRATEGIES",
    "MultiTargetResult",
    "reproduce",
    "strategy_scenario",
]

SCENARIOS = (
    "mt_bearings_crossing",
    "mt_radars_beams",
    "mt_appear_disappear",
    "mt_search_track",
    "mt_mixed_platforms",
)
LETTERS = dict(zip(SCENARIOS, "abcde", strict=True))  # the names of the scenarios
STRATEGIES = ("planner", "hold_course", "random_assignment")
BASELINES = STRATEGIES[1:]
MANAGER = "stonesoup_manager"  # Stone Soup's sensor manager, where it applies
MANAGER_SCENARIOS = ("mt_radars_beams", "mt_search_track")
# The margin per scene: the planner's GOSPA this far below the better baseline, and
# below each baseline with the paired interval excluding zero.
MARGINS = {
    "mt_bearings_crossing": 0.20,
    "mt_radars_beams": 0.05,
    "mt_appear_disappear": 0.05,
    "mt_search_track": 0.20,
    "mt_mixed_platforms": 0.20,
}


def strategy_scenario(scenario: Scenario, strategy: str) -> Scenario:
    """The scenario with the planner set up for ``strategy`` (one of :data:`STRATEGIES`)."""
    if strategy == "planner":
        return scenario
    if strategy == "hold_course":  # the beams as before the expected-GOSPA objective
        return with_changes(
            scenario, planner={"enabled": False, "targets": {"objective": "criterion"}}
        )
    if strategy == "random_assignment":
        return with_changes(scenario, planner={"targets": {"assignment": "random"}})
    raise ValueError(f"strategy must be one of {STRATEGIES}, got {strategy!r}")


@dataclass
class ScenarioResult:
    """One scenario: each strategy's batch summary."""

    name: str
    summaries: dict[str, BatchSummary]

    @property
    def strategies(self) -> tuple[str, ...]:
        """The strategies run here: :data:`STRATEGIES`, then :data:`MANAGER` if it was."""
        return tuple(self.summaries)

    def mean(self, strategy: str) -> float:
        return self.summaries[strategy].mean_gospa

    def stderr(self, strategy: str) -> float:
        g = np.asarray(self.summaries[strategy].run_gospa)
        return float(g.std(ddof=1) / math.sqrt(len(g))) if len(g) > 1 else math.nan

    def improvement(self, baseline: str) -> float:
        """1 - GOSPA(planner) / GOSPA(baseline)."""
        return 1.0 - self.mean("planner") / self.mean(baseline)

    def paired(self, baseline: str) -> PairedDifference:
        """GOSPA(planner) - GOSPA(baseline) run by run (negative: the planner is better); any
        strategy run here, :data:`MANAGER` too."""
        return paired_difference(
            self.summaries["planner"].run_gospa, self.summaries[baseline].run_gospa
        )

    def split(self, strategy: str) -> tuple[float, float, float]:
        """GOSPA's alpha = 2 split averaged over epochs and runs (Rahmathullah et al. 2017,
        eq. 2): localisation [m^p], missed targets and false tracks per epoch."""
        s = self.summaries[strategy]
        return (
            float(np.mean(s.localisation_t)),
            float(np.mean(s.missed_t)),
            float(np.mean(s.false_t)),
        )

    def gain_vs_best_baseline(self) -> float:
        """1 - GOSPA(planner) / GOSPA(the better baseline)."""
        return min(self.improvement(b) for b in BASELINES)

    def meets_margin(self) -> bool:
        """The issue's test of this scene: a gain of at least :data:`MARGINS` over the better
        baseline and, against each baseline, a paired 95 % interval wholly below zero."""
        return self.gain_vs_best_baseline() >= MARGINS[self.name] and all(
            self.paired(b).high < 0.0 for b in BASELINES
        )

    def improvement_stderr(self, baseline: str) -> float:
        """Standard error of :meth:`improvement` over runs (the runs are paired: same seeds)."""
        a = np.asarray(self.summaries["planner"].run_gospa)
        b = np.asarray(self.summaries[baseline].run_gospa)
        if len(a) < 2:
            return math.nan
        ma, mb = a.mean(), b.mean()
        # Delta method for the ratio of paired means.
        d = a / mb - ma * b / mb**2
        return float(d.std(ddof=1) / math.sqrt(len(a)))


@dataclass
class MultiTargetResult:
    runs: int
    scenarios: list[ScenarioResult] = field(default_factory=list)
    # Why Stone Soup's manager did not run where it applies ("": it ran, or was not asked for).
    manager_note: str = ""

    def table(self) -> list[dict[str, float | int | str]]:
        rows: list[dict[str, float | int | str]] = []
        for sc in self.scenarios:
            for strategy in sc.strategies:
                s = sc.summaries[strategy]
                d = None if strategy == "planner" else sc.paired(strategy)
                loc, missed, false = sc.split(strategy)
                rows.append(
                    {
                        "scenario": sc.name,
                        "strategy": strategy,
                        "runs": s.runs,
                        "mean_gospa_m": s.mean_gospa,
                        "stderr_m": sc.stderr(strategy),
                        "breaks_per_run": s.breaks,
                        "swaps_per_run": s.swaps,
                        # GOSPA's split per epoch: localisation [m^p], missed, false
                        "localisation_mp": loc,
                        "missed_per_epoch": missed,
                        "false_per_epoch": false,
                        "improvement": 0.0 if strategy == "planner" else sc.improvement(strategy),
                        # planner - this strategy, run by run, and its 95 % interval
                        "paired_diff_m": 0.0 if d is None else d.mean,
                        "paired_low_m": 0.0 if d is None else d.low,
                        "paired_high_m": 0.0 if d is None else d.high,
                    }
                )
        return rows

    def to_json(self) -> dict:
        return {
            "runs": self.runs,
            "manager_note": self.manager_note,
            "table": self.table(),
            "summaries": {
                sc.name: {k: v.to_json() for k, v in sc.summaries.items()} for sc in self.scenarios
            },
        }


def _run_manager(task: tuple[Scenario, int | None, int]) -> tuple[RunRecord, RunEvaluation]:
    """One run ``(scenario, run, candidates)`` with Stone Soup's manager pointing the beams and
    the platforms holding course, evaluated as :func:`run_batch` evaluates its runs."""
    scenario, run, candidates = task
    scenario = strategy_scenario(scenario, "hold_course")
    factory = functools.partial(stonesoup_manager.StoneSoupBeamManager, candidates=candidates)
    record = run_once(scenario, run, factory)
    return record, evaluate_run(scenario, record, component_rngs(scenario.seed, run)[3])


def run_manager_batch(
    scenario: Scenario,
    runs: int,
    jobs: int = 1,
    scheduler: Scheduler | None = None,
    candidates: int = stonesoup_manager.DEFAULT_CANDIDATES,
) -> BatchSummary:
    """:func:`run_batch` of ``scenario`` with Stone Soup's manager as the planner: the same run
    numbers (None for one run), so run r pairs with run r of every other strategy."""
    start = time.perf_counter()
    tasks = [(scenario, r if runs > 1 else None, candidates) for r in range(runs)]
    results = parallel_map(_run_manager, tasks, jobs, None, scheduler)
    return summarize(
        scenario,
        [record for record, _ in results],
        [ev for _, ev in results],
        time.perf_counter() - start,
    )


def reproduce(
    runs: int = 100,
    *,
    scenarios: Sequence[str] = SCENARIOS,
    jobs: int = 1,
    scheduler: Scheduler | None = None,
    scenarios_dir: str | Path | None = None,
    task_progress: Callable[[int, int], None] | None = None,
    stonesoup: bool | None = None,
) -> MultiTargetResult:
    """Every strategy on every scenario, ``runs`` seeded runs each (run r of every strategy
    draws the same truth and detections: common random numbers). Stone Soup's manager runs on
    :data:`MANAGER_SCENARIOS` if ``stonesoup`` (None: if it is installed); asked for and not
    installed, the result's ``manager_note`` says so and the rest runs."""
    check_jobs(jobs, scheduler)
    result = MultiTargetResult(runs)
    with_manager = (
        [n for n in scenarios if n in MANAGER_SCENARIOS] if stonesoup is not False else []
    )
    if with_manager and not stonesoup_manager.available():
        result.manager_note = (
            "Stone Soup's manager not run: stonesoup is not installed (make bench, or pip "
            "install -r requirements-bench.txt)"
        )
        with_manager = []
    tasks = TaskProgress(len(scenarios) * len(STRATEGIES) + len(with_manager), task_progress)
    with connected(scheduler) as cluster:
        for name in scenarios:
            base = load_scenario(scenario_path(name, scenarios_dir))
            summaries = {}
            for strategy in STRATEGIES:
                summaries[strategy] = run_batch(
                    strategy_scenario(base, strategy),
                    runs=runs,
                    jobs=jobs,
                    keep_records=False,
                    scheduler=cluster,
                )
                tasks.advance()
            if name in with_manager:
                summaries[MANAGER] = run_manager_batch(base, runs, jobs, cluster)
                summaries[MANAGER].records, summaries[MANAGER].evaluations = [], []
                tasks.advance()
            result.scenarios.append(ScenarioResult(name, summaries))
    return result


# Said under the verdicts when a margin is missed: where the 100-run figures and what bounds a
# missed margin are (six runs resolve few intervals; (b) misses at 100)
MISSED_NOTE = (
    'a missed margin: docs/multitarget.md, "Figures", gives each scene\'s 100-run result and '
    "what bounds a margin the planner misses there"
)


def format_report(res: MultiTargetResult) -> str:
    lines = [
        f"Multi-target active tracking: time-averaged GOSPA over {res.runs} seeded runs "
        f"(mean +- standard error, m)",
        "",
        f"{'scenario':24s} {'strategy':18s} {'GOSPA':>10s} {'+-':>7s} {'breaks':>7s} "
        f"{'swaps':>6s} {'improvement':>12s} {'loc m^p':>9s} {'missed':>7s} {'false':>6s}",
    ]
    for sc in res.scenarios:
        for strategy in sc.strategies:
            s = sc.summaries[strategy]
            imp = "" if strategy == "planner" else f"{100 * sc.improvement(strategy):11.1f}%"
            loc, missed, false = sc.split(strategy)
            lines.append(
                f"{sc.name:24s} {strategy:18s} {s.mean_gospa:10.1f} {sc.stderr(strategy):7.1f} "
                f"{s.breaks:7.2f} {s.swaps:6.2f} {imp:>12s} {loc:9.0f} {missed:7.3f} {false:6.3f}"
            )
    lines += [
        "",
        "(loc m^p, missed, false: GOSPA's split per epoch, eq. 2 of Rahmathullah et al. 2017)",
        "",
        "Paired differences GOSPA(planner) - GOSPA(baseline), run by run (m, 95 % interval):",
    ]
    for sc in res.scenarios:
        for b in sc.strategies[1:]:
            d = sc.paired(b)
            verdict = "resolved" if d.resolved else "not resolved"
            lines.append(
                f"{sc.name:24s} {'- ' + b:20s} {d.mean:+9.1f} [{d.low:+8.1f}, {d.high:+8.1f}]  "
                f"{verdict}"
            )
    if res.manager_note:
        lines.append(res.manager_note)
    lines.append("")
    judged = [(sc.name, sc.meets_margin()) for sc in res.scenarios if sc.name in MARGINS]
    verdicts = [
        f"{LETTERS.get(name, name)} {100 * MARGINS[name]:.0f}%: " + ("met" if met else "MISSED")
        for name, met in judged
    ]
    lines.append(
        "margin below the better baseline, both paired intervals below zero: " + ", ".join(verdicts)
    )
    if not all(met for _, met in judged):
        lines.append(MISSED_NOTE)
    gains = ",".join(
        f"{LETTERS.get(sc.name, sc.name)}:{100 * sc.gain_vs_best_baseline():.1f}"
        for sc in res.scenarios
    )
    lines.append(f"planner_gain_vs_best_baseline_pct={gains}")
    return "\n".join(lines)


def save_figures(res: MultiTargetResult, out: Path) -> list[Path]:
    """GOSPA vs time per scenario, the three strategies."""

    def figure(sc: ScenarioResult):
        fig, ax = figure_axes((7, 4))
        for strategy in sc.strategies:
            s = sc.summaries[strategy]
            t = s.dt * np.arange(1, s.steps + 1)
            ax.plot(t, s.gospa_t, label=f"{strategy} ({s.mean_gospa:.0f} m)")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("GOSPA [m]")
        ax.set_title(f"{sc.name}: mean GOSPA over {res.runs} runs")
        ax.legend()
        return fig

    return write_figures(
        [(f"gospa_{sc.name}.png", lambda sc=sc: figure(sc)) for sc in res.scenarios], out
    )


def _options(ap: argparse.ArgumentParser) -> None:
    ap.add_argument(
        "--scenario", action="append", choices=SCENARIOS, help="only these (repeatable)"
    )
    ap.add_argument(
        "--no-stonesoup",
        action="store_true",
        help=f"leave out Stone Soup's manager ({', '.join(MANAGER_SCENARIOS)}; run when installed)",
    )


REPRODUCTION = Reproduction(
    "multitarget",
    __doc__.splitlines()[0],
    RunsOption(1, 100, "Monte Carlo runs per row (100)"),
    options=_options,
    arguments=lambda args: dict(
        scenarios=tuple(args.scenario or SCENARIOS), stonesoup=False if args.no_stonesoup else None
    ),
)
main = REPRODUCTION.main


if __name__ == "__main__":
    raise SystemExit(main())
