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
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

__all__ = ["ENV_VAR", "kernels_enabled", "prefer_kernels"]

ENV_VAR = "ACTIVETRACK_KERNELS"
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
