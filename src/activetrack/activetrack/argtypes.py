"""argparse ``type=`` functions for numbers (and a scheduler address): a bad value is a
one-line usage error.

``ap.add_argument("--runs", type=int_in_range(1, MAX_RUNS))`` makes argparse print
``error: argument --runs: must be an integer in [1, 100000], got '0'`` and exit with code 2,
before anything runs. The limits are in :mod:`activetrack.limits`. Used by the experiments'
command lines here and by the ``activetrack`` command line (``activetrack_bringup.cli_types``).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

__all__ = [
    "SCHEDULER_HELP",
    "add_scheduler_option",
    "float_in_range",
    "int_in_range",
    "scheduler_address",
]


def _note(note: str) -> str:
    return f" ({note})" if note else ""


def int_in_range(lo: int, hi: int, *, note: str = "") -> Callable[[str], int]:
    """A type function accepting integers lo <= n <= hi (decimal digits, optional sign)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except (TypeError, ValueError):
            value = None
        if value is None or not lo <= value <= hi:
            raise argparse.ArgumentTypeError(
                f"must be an integer in [{lo}, {hi}]{_note(note)}, got {text!r}"
            )
        return value

    parse.__name__ = f"integer in [{lo}, {hi}]"
    return parse


def float_in_range(
    lo: float,
    hi: float,
    *,
    lo_inclusive: bool = True,
    hi_inclusive: bool = True,
    note: str = "",
) -> Callable[[str], float]:
    """A type function accepting finite numbers in the interval from lo to hi."""
    left, right = "[" if lo_inclusive else "(", "]" if hi_inclusive else ")"
    interval = f"{left}{lo:g}, {hi:g}{right}"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except (TypeError, ValueError):
            value = math.nan
        ok = (
            math.isfinite(value)
            and (value >= lo if lo_inclusive else value > lo)
            and (value <= hi if hi_inclusive else value < hi)
        )
        if not ok:
            raise argparse.ArgumentTypeError(
                f"must be a finite number in {interval}{_note(note)}, got {text!r}"
            )
        return value

    parse.__name__ = f"number in {interval}"
    return parse


SCHEDULER_HELP = (
    "run the Monte Carlo tasks on the Dask cluster of this scheduler (tcp://host:port; "
    "--jobs is then unused; docs/dask.md)"
)


def scheduler_address(text: str) -> str:
    """The ``--scheduler`` type: a Dask scheduler address that answers (``tcp://host:port``),
    checked by :func:`activetrack.montecarlo.dask.check_scheduler`, so a wrong or unreachable
    one is a usage error (``error: argument --scheduler: cannot reach ...``) before any work."""
    from activetrack.montecarlo.dask import SchedulerError, check_scheduler

    try:
        return check_scheduler(text)
    except SchedulerError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("scheduler: ")) from None


scheduler_address.__name__ = "scheduler address"


def add_scheduler_option(parser: argparse.ArgumentParser) -> None:
    """The ``--scheduler ADDRESS`` option of every Monte Carlo command (:func:`scheduler_address`,
    :data:`SCHEDULER_HELP`)."""
    parser.add_argument(
        "--scheduler", type=scheduler_address, metavar="ADDRESS", help=SCHEDULER_HELP
    )
