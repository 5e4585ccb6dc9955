"""The local backend: chunks of tasks on forked worker processes of this machine."""

from __future__ import annotations

import itertools
import multiprocessing
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import TypeVar

from activetrack.montecarlo.chunks import apply_chunk, even_chunks

__all__ = ["available_jobs", "local_map"]

T = TypeVar("T")
R = TypeVar("R")


def available_jobs() -> int:
    """The processors this process may run on (the affinity mask, not the machine's count)."""
    return len(os.sched_getaffinity(0))


def local_map(fn: Callable[[T], R], items: Sequence[T], jobs: int) -> Iterator[R]:
    """``fn(t)`` of every item, in order, on up to ``jobs`` forked worker processes (in this
    process for one job or one item). Workers are forked, so they see what the parent
    registered (sensor kinds, criteria) before the call."""
    workers = min(jobs, len(items))
    if workers <= 1:
        yield from (fn(t) for t in items)
        return
    context = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        done = pool.map(apply_chunk, [(fn, chunk) for chunk in even_chunks(items, workers)])
        yield from itertools.chain.from_iterable(done)
