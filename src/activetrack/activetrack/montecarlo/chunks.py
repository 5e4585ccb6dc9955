"""Tasks cut into chunks ``(fn, tasks)``: the unit both backends send to a worker, which
returns ``[fn(t) for t in tasks]``."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from typing import TypeVar

__all__ = ["CHUNKS_PER_WORKER", "apply_chunk", "even_chunks"]

T = TypeVar("T")
R = TypeVar("R")

CHUNKS_PER_WORKER = 4  # per process or Dask worker thread: a chunk's tail against round trips


def even_chunks(items: Sequence[T], workers: int) -> list[list[T]]:
    """``items`` cut, in order, into ``min(len(items), CHUNKS_PER_WORKER * workers)`` chunks
    whose sizes differ by one at most: fewer round trips than one task at a time, and no short
    last chunk that leaves a worker idle while another finishes (100 tasks on 2 workers: eight
    chunks of 12-13, not eight of 12 and one of 4)."""
    parts = max(1, min(len(items), CHUNKS_PER_WORKER * workers))
    size, extra = divmod(len(items), parts)
    bounds = [i * size + min(i, extra) for i in range(parts + 1)]
    return [list(items[a:b]) for a, b in itertools.pairwise(bounds)]


def apply_chunk(chunk: tuple[Callable[[T], R], list[T]]) -> list[R]:
    """``[fn(t) for t in tasks]`` of one chunk ``(fn, tasks)``."""
    fn, tasks = chunk
    return [fn(t) for t in tasks]
