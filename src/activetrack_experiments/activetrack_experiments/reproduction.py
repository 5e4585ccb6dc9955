"""What every paper reproduction shares: the command line ``activetrack reproduce NAME`` and the
Monte Carlo plumbing.

A paper's module ``activetrack_experiments.NAME`` computes (``reproduce(runs=, jobs=,
scheduler=, task_progress=, ...)``: ``jobs`` worker processes or the Dask cluster ``scheduler``,
``task_progress(done, total)`` called as tasks finish; neither changes the numbers), formats
(``format_report(res)``) and draws (``save_figures(res, out)``); ``res.to_json()`` is the JSON
document. Its command line is a :class:`Reproduction`::

    REPRODUCTION = Reproduction(
        "fifth",  # activetrack_experiments.fifth: activetrack reproduce fifth
        "Reproduce Fifth (2030) Table 1.",
        RunsOption(1, 100, "Monte Carlo runs per row (100)"),
        options=lambda ap: ap.add_argument("--seed", type=int_in_range(0, MAX_SEED), default=0),
        arguments=lambda args: dict(seed=args.seed),
    )
    main = REPRODUCTION.main
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import import_module
from pathlib import Path
from typing import Any, TypeVar

from activetrack.argtypes import add_scheduler_option, int_in_range
from activetrack.limits import MAX_JOBS, MAX_RUNS
from activetrack.montecarlo import Progress, Scheduler, available_jobs, parallel_map
from activetrack.plots import new_figure
from activetrack.strict_json import write_json

__all__ = ["Reproduction", "RunsOption", "figure_axes", "map_groups", "split"]

T = TypeVar("T")
V = TypeVar("V")


@dataclass(frozen=True)
class RunsOption:
    """A paper's ``--runs``: an integer in [lo, MAX_RUNS] (``note`` explains ``lo`` in the usage
    error), ``default`` (None: the paper's ``reproduce`` chooses, e.g. by ``--quick``)."""

    lo: int
    default: int | None
    help: str
    note: str = ""


@dataclass(frozen=True)
class Reproduction:
    """One paper's command line; :meth:`main` is its entry point.

    ``name``: of the module and of ``activetrack reproduce NAME`` (figures in
    ``runs/reproduce-NAME`` by default). The driver adds ``--runs``, ``--jobs``, ``--scheduler``,
    ``--json``, ``--out`` and ``--no-figures``; ``options(parser)`` adds the paper's own and
    ``check(args)`` completes them (a ValueError naming the option is a usage error, exit code 2).
    The module's ``reproduce`` is called with ``runs``, ``jobs``, ``scheduler``,
    ``task_progress`` and ``arguments(args)``. Left None, ``report`` and ``figures`` are the
    module's ``format_report`` and ``save_figures(res, args.out)``, and ``document(res,
    figures, wall_time_s)`` is ``res.to_json()``.
    """

    name: str
    description: str
    runs: RunsOption
    report: Callable[[Any], str] | None = None
    figures: Callable[[Any, argparse.Namespace], list[Path]] | None = None
    options: Callable[[argparse.ArgumentParser], Any] | None = None
    check: Callable[[argparse.Namespace], None] | None = None
    arguments: Callable[[argparse.Namespace], dict] = lambda args: {}
    document: Callable[[Any, list[Path], float], dict] | None = None

    def _paper(self, attr: str, given: Callable | None = None) -> Callable:
        return given or getattr(import_module(f"activetrack_experiments.{self.name}"), attr)

    def parser(self) -> argparse.ArgumentParser:
        ap = argparse.ArgumentParser(
            prog=f"activetrack reproduce {self.name}", description=self.description
        )
        runs = self.runs
        runs_type = int_in_range(runs.lo, MAX_RUNS, note=runs.note)
        ap.add_argument("--runs", type=runs_type, default=runs.default, help=runs.help)
        if self.options is not None:
            self.options(ap)
        ap.add_argument(
            "--jobs",
            type=int_in_range(1, MAX_JOBS),
            default=available_jobs(),
            help="worker processes (the numbers do not depend on it)",
        )
        add_scheduler_option(ap)
        ap.add_argument("--json", type=Path, help="write the numbers to this file")
        ap.add_argument(
            "--out",
            type=Path,
            default=Path(f"runs/reproduce-{self.name}"),
            help="figure directory (with the numbers as results.json)",
        )
        ap.add_argument("--no-figures", action="store_true", help="do not write PNG figures")
        return ap

    def parse(self, argv: Sequence[str]) -> argparse.Namespace:
        """The options of ``argv``, checked (a usage error exits with code 2)."""
        ap = self.parser()
        args = ap.parse_args(argv)
        try:
            if self.check is not None:
                self.check(args)
        except ValueError as exc:
            ap.error(str(exc))
        return args

    def main(
        self,
        argv: Sequence[str] | None = None,
        *,
        task_progress: Callable[[int, int], None] | None = None,
    ) -> int:
        """``activetrack reproduce NAME`` with ``argv`` (default: ``sys.argv[1:]``): run, print
        the report (stdout), the figures written and the wall time (stderr), write the JSON
        document; 0."""
        args = self.parse(sys.argv[1:] if argv is None else argv)
        start = time.perf_counter()
        kw = dict(jobs=args.jobs, scheduler=args.scheduler, task_progress=task_progress)
        res = self._paper("reproduce")(runs=args.runs, **kw, **self.arguments(args))
        print(self._paper("format_report", self.report)(res))
        if args.no_figures:
            figures = []
        elif self.figures is not None:
            figures = self.figures(res, args)
        else:
            figures = self._paper("save_figures")(res, args.out)
        # On stderr: the report is stdout's last lines (multitarget's last is the gain key)
        if figures:
            print("figures: " + ", ".join(str(f) for f in figures), file=sys.stderr)
        wall_time_s = time.perf_counter() - start
        print(f"wall time {wall_time_s:.1f} s", file=sys.stderr)
        doc = res.to_json() if self.document is None else self.document(res, figures, wall_time_s)
        paths = [] if args.no_figures else [args.out / "results.json"]
        for path in paths + ([args.json] if args.json is not None else []):
            write_json(path, doc)  # NaN (a row without a figure) as null
        return 0


def figure_axes(figsize: tuple[float, float], *grid: int, **kw: Any):
    """A new figure (:func:`activetrack.plots.new_figure`) and ``fig.subplots(*grid, **kw)``."""
    fig = new_figure(figsize=figsize)
    return fig, fig.subplots(*grid, **kw)


def split(items: Sequence[T], sizes: Sequence[int]) -> list[list[T]]:
    """``items`` cut, in order, into consecutive groups of ``sizes``."""
    starts = [sum(sizes[:i]) for i in range(len(sizes))]
    return [list(items[s : s + n]) for s, n in zip(starts, sizes, strict=True)]


def map_groups(
    fn: Callable[[T], V],
    groups: Sequence[Sequence[T]],
    jobs: int = 1,
    progress: Progress | None = None,
    scheduler: Scheduler | None = None,
) -> list[list[V]]:
    """``fn`` of every task of every group in one :func:`activetrack.montecarlo.parallel_map`
    (the workers stay busy across groups), the results grouped as the tasks were."""
    done = parallel_map(fn, [task for group in groups for task in group], jobs, progress, scheduler)
    return split(done, [len(group) for group in groups])
