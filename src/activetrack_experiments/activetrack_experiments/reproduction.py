"""What every paper reproduction shares: the command line ``activetrack reproduce NAME`` and the
Monte Carlo plumbing.

A paper's module computes (``reproduce(runs=, jobs=, scheduler=, task_progress=, ...)``
returns a results object whose ``to_json()`` is the JSON document), formats (the report it
prints) and draws (``save_figures``). Its command line is a :class:`Reproduction` that names
these, the options it adds and how they map to the other arguments of ``reproduce``; the driver
adds the options every paper takes (``--runs`` with the paper's range and default, ``--jobs``,
``--scheduler``, ``--json``, ``--out``, ``--no-figures``), runs, prints the report, writes the
figures with the document beside them (``OUT/results.json``) and the document to ``--json``::

    def _options(parser):
        parser.add_argument("--seed", type=int_in_range(0, MAX_SEED), default=0)

    REPRODUCTION = Reproduction(
        name="fifth",  # activetrack reproduce fifth
        description="Reproduce Fifth (2030) Table 1.",
        runs=RunsOption(1, 100, "Monte Carlo runs per row (100)"),
        reproduce=reproduce,
        report=format_report,
        figures=lambda res, args: save_figures(res, args.out),
        options=_options,
        arguments=lambda args: dict(seed=args.seed),
    )
    main = REPRODUCTION.main
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Generic, Protocol, TypeVar

from activetrack.argtypes import add_scheduler_option, int_in_range
from activetrack.limits import MAX_JOBS, MAX_RUNS
from activetrack.montecarlo import Progress, Scheduler, available_jobs, parallel_map

__all__ = ["Reproduction", "Results", "RunsOption", "map_groups", "split"]

T = TypeVar("T")
V = TypeVar("V")

# Called with (tasks done, tasks in all): the command line's progress bar.
TaskReport = Callable[[int, int], None]


class Results(Protocol):
    """What a paper's ``reproduce`` returns: its JSON document, tables and arrays."""

    def to_json(self) -> dict: ...


R = TypeVar("R", bound=Results)


@dataclass(frozen=True)
class RunsOption:
    """A paper's ``--runs``: an integer in [lo, MAX_RUNS] (``note`` explains ``lo`` in the usage
    error), ``default`` (None: the paper's ``reproduce`` chooses, e.g. by ``--quick``)."""

    lo: int
    default: int | None
    help: str
    note: str = ""


def _no_options(parser: argparse.ArgumentParser) -> None:
    pass


def _no_check(args: argparse.Namespace) -> None:
    pass


def _no_arguments(args: argparse.Namespace) -> dict:
    return {}


def _to_json(res: Results, figures: list[Path], wall_time_s: float) -> dict:
    return res.to_json()


@dataclass(frozen=True)
class Reproduction(Generic[R]):
    """One paper's command line; :meth:`main` is its entry point.

    ``name``: ``activetrack reproduce NAME``, figures in ``runs/reproduce-NAME`` by default;
    ``description``: the first line of ``--help``; ``reproduce``: the paper's, called with
    ``runs``, ``jobs``, ``scheduler``, ``task_progress`` and ``arguments(args)``; ``report(res)``:
    the text printed; ``figures(res, args)`` writes the figures into ``args.out`` and returns
    the files; ``options(parser)`` adds the paper's own options; ``check(args)`` completes and
    checks them (a ValueError is a usage error, exit code 2, whose message names the option);
    ``document(res, figures, wall_time_s)``: the JSON document (``res.to_json()``).
    """

    name: str
    description: str
    runs: RunsOption
    reproduce: Callable[..., R]
    report: Callable[[R], str]
    figures: Callable[[R, argparse.Namespace], list[Path]]
    options: Callable[[argparse.ArgumentParser], None] = _no_options
    check: Callable[[argparse.Namespace], None] = _no_check
    arguments: Callable[[argparse.Namespace], dict] = _no_arguments
    document: Callable[[R, list[Path], float], dict] = _to_json

    def parser(self) -> argparse.ArgumentParser:
        ap = argparse.ArgumentParser(
            prog=f"activetrack reproduce {self.name}", description=self.description
        )
        runs = self.runs
        ap.add_argument(
            "--runs",
            type=int_in_range(runs.lo, MAX_RUNS, note=runs.note),
            default=runs.default,
            help=runs.help,
        )
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
            self.check(args)
        except ValueError as exc:
            ap.error(str(exc))
        return args

    def main(
        self, argv: Sequence[str] | None = None, *, task_progress: TaskReport | None = None
    ) -> int:
        """``activetrack reproduce NAME`` with ``argv`` (default: ``sys.argv[1:]``): run, print
        the report, the figures written and the wall time, write the JSON document; 0.
        ``task_progress(done, total)`` is called as the Monte Carlo tasks finish (the command
        line's progress bar); it does not change the numbers."""
        args = self.parse(sys.argv[1:] if argv is None else argv)
        start = time.perf_counter()
        res = self.reproduce(
            runs=args.runs,
            jobs=args.jobs,
            scheduler=args.scheduler,
            task_progress=task_progress,
            **self.arguments(args),
        )
        print(self.report(res))
        figures = [] if args.no_figures else self.figures(res, args)
        if figures:
            print("\nfigures: " + ", ".join(str(f) for f in figures))
        wall_time_s = time.perf_counter() - start
        print(f"wall time {wall_time_s:.1f} s")
        text = json.dumps(self.document(res, figures, wall_time_s), indent=2)
        paths = [] if args.no_figures else [args.out / "results.json"]
        for path in paths + ([args.json] if args.json is not None else []):
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
        return 0


def split(items: Sequence[T], sizes: Sequence[int]) -> list[list[T]]:
    """``items`` cut, in order, into consecutive groups of ``sizes``."""
    out, start = [], 0
    for size in sizes:
        out.append(list(items[start : start + size]))
        start += size
    return out


def map_groups(
    fn: Callable[[T], V],
    groups: Sequence[Sequence[T]],
    jobs: int = 1,
    progress: Progress | None = None,
    scheduler: Scheduler | None = None,
) -> list[list[V]]:
    """``fn`` of every task of every group in one :func:`activetrack.montecarlo.parallel_map`
    (the workers stay busy across groups), the results grouped as the tasks were."""
    flat = [task for group in groups for task in group]
    done = parallel_map(fn, flat, jobs, progress, scheduler)
    return split(done, [len(group) for group in groups])
