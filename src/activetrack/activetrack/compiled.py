"""The switch between the compiled kernels (numba) and their numpy reference forms.

``ACTIVETRACK_KERNELS=numpy`` in the environment makes every consumer take the numpy form (the
reference the kernels are tested against); anything else, or nothing, takes the compiled one.
Read at each call, so a test or a session can flip it; numba is imported only by the kernel
modules themselves, on first use.
"""

from __future__ import annotations

import os

__all__ = ["ENV_VAR", "kernels_enabled"]

ENV_VAR = "ACTIVETRACK_KERNELS"


def kernels_enabled() -> bool:
    """False when ``ACTIVETRACK_KERNELS=numpy``: use the numpy forms."""
    return os.environ.get(ENV_VAR, "auto") != "numpy"
