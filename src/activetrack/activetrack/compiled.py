"""When the compiled kernels (numba) run instead of their numpy reference forms.

numba's own start-up (importing it and initialising its compiler to load the cached machine
code) costs about half a second to a second per process, more than a light workload (a
single-step planning decision, one bound along a path) gains from the kernels. So the kernels
run when

- the environment says ``ACTIVETRACK_KERNELS=compiled``; or
- the caller expects heavy work and says so with :func:`prefer_kernels` (the planner does for a
  decision scoring at least ``planner.HEAVY_DECISION`` candidates per platform); or
- numba is loaded in this process already (the start-up is paid: every kernel is then worth
  it);

and never with ``ACTIVETRACK_KERNELS=numpy`` (the reference the kernels are tested against).
The kernels and the numpy forms agree to round-off (1e-12, tested), so the choice changes no
printed figure. Read at each call; numba is imported only by the kernel modules themselves.

numba compiles a kernel on its first call and caches the machine code (``cache=True``, next to
the module or in ``NUMBA_CACHE_DIR``); compiling them all takes half a minute on a busy 2-core
machine, loading them from the cache about a second. ``python -m activetrack.compiled`` (or
:func:`warm_up`) compiles every kernel module of ``KERNEL_MODULES`` ahead of the first run,
e.g. at setup.
"""

from __future__ import annotations

import importlib
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

__all__ = ["ENV_VAR", "KERNEL_MODULES", "kernels_enabled", "prefer_kernels", "warm_up"]

ENV_VAR = "ACTIVETRACK_KERNELS"
# The modules with compiled kernels; each has a warm_up() that calls every kernel once.
KERNEL_MODULES = (
    "activetrack.models._fisher_kernels",
    "activetrack.bounds._kernels",
    "activetrack.planning._kernels",
)
_PREFERRED: ContextVar[bool] = ContextVar("activetrack_prefer_kernels", default=False)


def kernels_enabled() -> bool:
    """Whether a consumer should take its compiled kernel now (see the module docstring)."""
    mode = os.environ.get(ENV_VAR, "auto")
    if mode == "numpy":
        return False
    return mode == "compiled" or _PREFERRED.get() or "numba" in sys.modules


@contextmanager
def prefer_kernels(prefer: bool = True) -> Iterator[None]:
    """Within the block, take the compiled kernels (``prefer``) even before numba is loaded:
    the caller expects enough work to pay for numba's start-up."""
    token = _PREFERRED.set(bool(prefer))
    try:
        yield
    finally:
        _PREFERRED.reset(token)


def warm_up() -> dict[str, float]:
    """Compile (or load from numba's cache) every kernel of ``KERNEL_MODULES``: seconds each."""
    out = {}
    with prefer_kernels():
        for name in KERNEL_MODULES:
            t0 = time.perf_counter()
            importlib.import_module(name).warm_up()
            out[name] = time.perf_counter() - t0
    return out


if __name__ == "__main__":
    for module, seconds in warm_up().items():
        print(f"{module}: ready in {seconds:.1f} s")
