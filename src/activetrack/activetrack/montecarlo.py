"""The one parallel Monte Carlo of the library: seeded tasks mapped over worker processes.

Every task carries its own seed (run r of a batch draws from ``SeedSequence([seed, r])``), so
a result never depends on which process ran a task or how many there were: ``jobs=1`` and
``jobs=N`` give bit-identical results, in task order. ``run_batch`` and every reproduction of
the experiments package go through :func:`parallel_map`.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import TypeVar

__all__ = ["available_jobs", "check_jobs", "parallel_map"]

T = TypeVar("T")
R = TypeVar("R")


def available_jobs() -> int:
    """The processors this process may run on (the affinity mask, not the machine's count)."""
    return len(os.sched_getaffinity(0))


def check_jobs(jobs: int) -> int:
    """``jobs`` if it is a usable worker count (an int >= 1), else a ValueError naming it."""
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs: must be an integer >= 1, got {jobs!r}")
    return jobs


def parallel_map(fn: Callable[[T], R], tasks: Iterable[T], jobs: int = 1) -> list[R]:
    """``[fn(t) for t in tasks]``, on up to ``jobs`` worker processes, in task order.

    ``fn`` and the tasks must be picklable (a module-level function and plain data). Workers
    are forked, so they see what the parent registered (sensor kinds, criteria) before the
    call. With ``jobs=1`` or a single task everything runs in this process. An exception in a
    task is raised here, with its traceback.
    """
    check_jobs(jobs)
    items: Sequence[T] = list(tasks)
    workers = min(jobs, len(items))
    if workers <= 1:
        return [fn(t) for t in items]
    # Larger chunks cost less IPC; four chunks per worker still balance uneven tasks.
    chunksize = max(1, len(items) // (4 * workers))
    context = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        return list(pool.map(fn, items, chunksize=chunksize))
