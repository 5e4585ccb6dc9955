"""Keep numpy's mid-sized temporaries on the heap (glibc malloc tuning, process-wide).

The planner and the particle filter create many short-lived arrays of 0.1-10 MB (1,000
samples x tens of candidates, 10,000 particles x 4). glibc serves those with mmap and, once
freed, returns them to the kernel, so every new array page-faults its pages back in: measured
here, ``dx * dx + dy * dy`` on 45 x 1,000 arrays took 0.5 ms instead of 0.05 ms, and a two-step
3-sensor planning run spent 40 % of its time in the kernel. Raising the mmap and trim
thresholds makes freed blocks reusable. Results do not change, only speed.

Applied once when ``activetrack`` is imported, on glibc only; skipped when the user set any
``MALLOC_*`` variable (theirs wins) or ``ACTIVETRACK_MALLOC_TUNING=0``. A Dask worker's
``MALLOC_TRIM_THRESHOLD_`` comes from Dask's own defaults, not from the user: the Monte Carlo
tasks name it in ``ignore`` (activetrack.montecarlo.dask).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
from collections.abc import Collection

M_TRIM_THRESHOLD = -1  # glibc <malloc.h>
M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD = 32 * 1024 * 1024  # bytes: blocks below this come from the heap
TRIM_THRESHOLD = 128 * 1024 * 1024  # bytes of free heap top kept before giving it back

_applied: bool | None = None


def allocator_tuned() -> bool:
    """Whether :func:`tune_allocator` applied the tuning in this process (a Dask worker does
    the same for a client that did: activetrack.montecarlo.dask)."""
    return bool(_applied)


def tune_allocator(ignore: Collection[str] = ()) -> bool:
    """Set glibc's mmap and trim thresholds; True if applied (idempotent). ``ignore``: names of
    ``MALLOC_*`` variables that were not the user's choice (they do not prevent the tuning).

    A refusal is not final: a later call with other ``ignore`` names decides afresh (a Dask
    worker may have refused once, at the import of a script's module, before its first task
    says which variable is Dask's)."""
    global _applied
    if _applied:
        return True
    _applied = False
    if not sys.platform.startswith("linux") or os.environ.get("ACTIVETRACK_MALLOC_TUNING") == "0":
        return False
    if any(k.startswith("MALLOC_") and k not in ignore for k in os.environ):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc (e.g. musl): nothing to tune
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    _applied = bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(
        mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD)
    )
    return _applied
