"""Compiled kernels (numba) for the hot loops, with the numpy code kept as the reference.

Which path runs is one process-wide switch, read from the environment variable
``ACTIVETRACK_KERNELS`` at first use:

- ``auto`` (the default): the compiled kernels when numba imports, numpy otherwise;
- ``numpy``: always the numpy code (the reference the kernels are tested against);
- ``compiled``: the compiled kernels; an ImportError if numba is missing.

:func:`set_kernels` changes it within a process (tests and benchmarks compare both paths).

numba is imported only when a kernel is first asked for (:func:`particle_kernels`), so a process
that never runs a particle filter pays nothing. Every kernel is compiled with ``cache=True``:
the machine code is kept in ``__pycache__`` next to the source and loaded from there by later
processes; ``make setup`` compiles them once (:func:`warm_up`).

The consumers stay free of type tests (``tests/core/test_no_type_dispatch.py``): a built-in
sensor or motion model calls the kernel inside its own method (e.g.
``BearingSensor.log_likelihood``, ``NearlyConstantVelocity.sample``), so a sensor or model
without a kernel simply runs its numpy maths.
"""

from __future__ import annotations

import os
from types import ModuleType

__all__ = ["ENV_VAR", "MODES", "compiled_enabled", "particle_kernels", "set_kernels", "warm_up"]

ENV_VAR = "ACTIVETRACK_KERNELS"
MODES = ("auto", "numpy", "compiled")

# The chosen mode (None: not read from the environment yet) and the loaded kernel module.
_mode: str | None = None
_particle: ModuleType | None = None
_unavailable = False  # "auto" found no numba: do not retry the import at every call


def _check_mode(mode: str) -> str:
    if mode not in MODES:
        raise ValueError(f"{ENV_VAR} / set_kernels: mode must be one of {MODES}, got {mode!r}")
    return mode


def set_kernels(mode: str | None) -> None:
    """Choose ``"auto"``, ``"numpy"`` or ``"compiled"`` for this process; None goes back to
    the environment variable ``ACTIVETRACK_KERNELS``."""
    global _mode
    _mode = None if mode is None else _check_mode(mode)


def _current_mode() -> str:
    global _mode
    if _mode is None:
        _mode = _check_mode(os.environ.get(ENV_VAR, "auto").strip().lower() or "auto")
    return _mode


def particle_kernels() -> ModuleType | None:
    """The compiled particle-filter kernels (:mod:`activetrack.kernels.particle`), or None
    when the numpy path is chosen or (in ``auto`` mode) numba does not import."""
    global _particle, _unavailable
    mode = _current_mode()
    if mode == "numpy" or (mode == "auto" and _unavailable):
        return None
    if _particle is None:
        try:
            from activetrack.kernels import particle
        except ImportError:
            if mode == "compiled":
                raise
            _unavailable = True
            return None
        _particle = particle
    return _particle


def compiled_enabled() -> bool:
    """True when the compiled kernels run (see the module docstring)."""
    return particle_kernels() is not None


def warm_up() -> bool:
    """Compile (or load from the disk cache) every particle kernel once; False without numba."""
    kernels = particle_kernels()
    if kernels is None:
        return False
    kernels.warm_up()
    return True
