""":func:`parallel_map`, the one entry of the Monte Carlo (package docstring), and progress.

Every task carries its own seed (run r of a batch draws from ``SeedSequence([seed, r])``), so
``jobs=1``, ``jobs=N`` and a Dask cluster give bit-identical results, in task order.
``run_batch`` and every reproduction of the experiments package go through it.

Progress: the library never prints. ``progress(done)`` is called in the calling process as
tasks finish; :class:`TaskProgress` adds up several maps (and steps of other work) for one
``(done, total)`` callback, from which the command line draws its progress bars.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import TypeVar

from activetrack.montecarlo.dask import Scheduler, check_scheduler, dask_map  # stdlib-only
from activetrack.montecarlo.local import local_map

__all__ = ["Progress", "TaskProgress", "check_jobs", "parallel_map"]

T = TypeVar("T")
R = TypeVar("R")

# Called with the number of tasks done so far (1, 2, ..., N).
Progress = Callable[[int], None]


def check_jobs(jobs: int, scheduler: Scheduler | None = None) -> int:
    """``jobs`` if it is a usable worker count (an int >= 1), else a ValueError naming it; with
    a ``scheduler`` address, also that it answers (a SchedulerError, a ValueError, otherwise:
    :func:`activetrack.montecarlo.dask.check_scheduler`), so a reproduction fails before its
    first task rather than at its first map."""
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs: must be an integer >= 1, got {jobs!r}")
    if isinstance(scheduler, str):
        check_scheduler(scheduler)
    return jobs


def parallel_map(
    fn: Callable[[T], R],
    tasks: Iterable[T],
    jobs: int = 1,
    progress: Progress | None = None,
    scheduler: Scheduler | None = None,
) -> list[R]:
    """``[fn(t) for t in tasks]``, on up to ``jobs`` forked worker processes (:mod:`.local`),
    in task order; ``fn`` and the tasks must be picklable. An exception in a task is raised
    here, with its traceback. ``progress(done)`` is called once per task as the results come in
    (done = 1, ..., len(tasks)); it is never pickled.

    ``scheduler`` (an address ``tcp://host:port`` or a ``distributed.Client``): the tasks run
    on that Dask cluster's workers instead (``jobs`` is not used; :mod:`.dask`); a bad address
    raises :class:`~activetrack.montecarlo.dask.SchedulerError` before any task runs.
    """
    check_jobs(jobs)
    items: Sequence[T] = list(tasks)
    if scheduler is not None:
        return _collect(dask_map(fn, items, scheduler), progress)
    return _collect(local_map(fn, items, jobs), progress)


def _collect(results: Iterator[R], progress: Progress | None) -> list[R]:
    out: list[R] = []
    for result in results:
        out.append(result)
        if progress is not None:
            progress(len(out))
    return out


class TaskProgress:
    """One ``report(done, total)`` callback over work done in parts: several
    :func:`parallel_map` calls (:meth:`of_map`) and single steps (:meth:`advance`).

    ``total`` is the count of all parts' tasks, known up front; ``report`` None: nothing is
    reported (the methods stay usable, so callers need no branches).
    """

    def __init__(self, total: int, report: Callable[[int, int], None] | None) -> None:
        self.total = total
        self.done = 0
        self._report = report

    def advance(self, tasks: int = 1) -> None:
        """``tasks`` more tasks are done."""
        self.done += tasks
        if self._report is not None:
            self._report(self.done, self.total)

    def of_map(self) -> Progress | None:
        """The ``progress`` argument of one :func:`parallel_map` call that is part of the work."""
        if self._report is None:
            return None
        start = self.done

        def report(done: int) -> None:
            self.advance(start + done - self.done)

        return report
