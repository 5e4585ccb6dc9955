"""Compiled kernels (numba) for the hot loops, with the numpy code kept as the reference.

The particle-filter step kernels (:func:`particle_kernels`) do the very operations of their numpy
references, in the same order and on the same random draws: the same particles and weights bit
for bit (tests/core/test_pf_kernels.py), so which one runs changes the speed, never a result.

One process-wide switch, ``ACTIVETRACK_KERNELS`` (or :func:`set_kernels`), decides for every
kernel, the filters' here and the planner's (``models._fisher_kernels``, ``bounds._kernels``,
``planning._kernels``; docs/planning-speed.md):

- ``auto`` (the default): numpy first, the compiled kernels once they pay off: as soon as numba
  is imported or once the process has done :data:`AUTO_WORK` particle updates (particles x
  steps). Loading numba costs about 0.5 s of CPU per process, what the numpy path spends on
  that much work: ``activetrack run`` on the default scenario never pays it, a Monte Carlo
  campaign once. The planner's kernels, equal to numpy to round-off only
  (:func:`kernels_enabled`), run in ``auto`` only inside :func:`prefer_kernels` (a decision of
  at least ``planning.planner.HEAVY_DECISION`` candidates per platform), never because of what
  ran before, so a Monte Carlo task gives the same bits on every worker. Without numba: numpy.
- ``numpy``: always the numpy code;
- ``compiled``: the compiled kernels from the first step (ImportError without numba), also
  the EKF (:func:`ekf_kernels`) and particle moments (:func:`moment_kernels`), which agree
  with numpy's BLAS products to round-off only and so are left out of ``auto``.

Every kernel is compiled with ``cache=True`` (machine code in ``__pycache__``); ``make setup``
compiles them once (:func:`warm_up`; ``python -m activetrack.kernels`` by hand). Consumers stay
free of type tests (tests/core/test_no_type_dispatch.py): a built-in sensor or motion model
calls its kernel inside its own method, so one without a kernel runs its own numpy maths.
"""

from __future__ import annotations

import importlib
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from types import ModuleType

__all__ = [
    "AUTO_WORK",
    "ENV_VAR",
    "MODES",
    "compiled_enabled",
    "ekf_kernels",
    "expect_particle_work",
    "moment_kernels",
    "particle_kernels",
    "set_kernels",
    "warm_up",
]

ENV_VAR = "ACTIVETRACK_KERNELS"
MODES = ("auto", "numpy", "compiled")
# Particle updates (particles x steps) after which "auto" loads numba: 5e6 is ~500 steps of
# 10,000 particles, ~0.5 s of the numpy path.
AUTO_WORK = 5_000_000
# The modules whose warm_up() calls every compiled kernel once (the planner's, of
# planning._kernels, beside the search that drives them).
KERNEL_MODULES = (
    "activetrack.kernels.pcg64",
    "activetrack.kernels.particle",
    "activetrack.kernels.ekf",
    "activetrack.kernels.moments",
    "activetrack.models._fisher_kernels",
    "activetrack.bounds._kernels",
    "activetrack.planning.horizons",
)
_PREFERRED: ContextVar[bool] = ContextVar("activetrack_prefer_kernels", default=False)

# The mode set_kernels chose (None: the environment's), the loaded kernel modules and the
# particle updates counted so far.
_mode: str | None = None
_particle: ModuleType | None = None
_compiled_only: dict[str, ModuleType] = {}
_unavailable = False  # numba did not import: do not retry at every call
_work = 0


def _check_mode(mode: str) -> str:
    if mode not in MODES:
        raise ValueError(f"{ENV_VAR} / set_kernels: mode must be one of {MODES}, got {mode!r}")
    return mode


def set_kernels(mode: str | None) -> None:
    """Choose ``"auto"``, ``"numpy"`` or ``"compiled"`` for this process; None goes back to
    the environment variable ``ACTIVETRACK_KERNELS``."""
    global _mode
    _mode = None if mode is None else _check_mode(mode)


# os.environ's own table of bytes: reading it skips encoding the key and decoding the value,
# most of the 0.7 us an os.environ.get costs (the particle filter asks several times a step).
# The value read last and its mode are kept: a changed variable is parsed again.
_ENV_TABLE = getattr(os.environ, "_data", None)
_ENV_KEY = os.fsencode(ENV_VAR)
_env_parsed: tuple[object, str] = (None, "auto")


def _current_mode() -> str:
    global _env_parsed
    if _mode is not None:
        return _mode
    if _ENV_TABLE is None:  # not CPython's os.environ
        return _check_mode(os.environ.get(ENV_VAR, "auto").strip().lower() or "auto")
    raw = _ENV_TABLE.get(_ENV_KEY)
    seen, mode = _env_parsed
    if raw is seen:
        return mode
    mode = "auto" if raw is None else (os.fsdecode(raw).strip().lower() or "auto")
    _env_parsed = (raw, _check_mode(mode))
    return mode


def kernels_enabled() -> bool:
    """Whether a kernel that agrees with its numpy reference to round-off (the planner's: the
    Fisher information, the eq. 3 prediction, b_k) runs now: in ``compiled`` mode, and in
    ``auto`` inside :func:`prefer_kernels` only (never because numba happens to be loaded, so
    a result does not depend on what the process ran before)."""
    mode = _current_mode()
    return mode == "compiled" or (mode == "auto" and _PREFERRED.get())


@contextmanager
def prefer_kernels(prefer: bool = True) -> Iterator[None]:
    """Within the block, :func:`kernels_enabled` in ``auto`` mode is ``prefer``: the caller
    expects (or not) enough work to pay for numba's start-up."""
    token = _PREFERRED.set(bool(prefer))
    try:
        yield
    finally:
        _PREFERRED.reset(token)


def _load(mode: str) -> ModuleType | None:
    global _particle, _unavailable
    try:
        from activetrack.kernels import particle
    except ImportError:
        if mode == "compiled":
            raise
        _unavailable = True
        return None
    _particle = particle
    return particle


def particle_kernels(work: int = 0) -> ModuleType | None:
    """The compiled particle-filter kernels (:mod:`activetrack.kernels.particle`), or None
    for the numpy path (see the module docstring). ``work``: particle updates to count
    towards :data:`AUTO_WORK` (the particle filter passes its N once per update)."""
    global _work
    _work += work
    if _particle is not None:
        return None if _current_mode() == "numpy" else _particle
    mode = _current_mode()
    if mode == "numpy" or (_unavailable and mode == "auto"):
        return None
    if mode == "auto" and _work < AUTO_WORK and "numba" not in sys.modules:
        return None
    return _load(mode)


def expect_particle_work(work: int) -> None:
    """Announce ``work`` particle updates (particles x steps x runs) about to be done, by this
    process or by workers it forks: in ``auto`` mode they count towards :data:`AUTO_WORK` now,
    so a Monte Carlo of particle filters loads the kernels once, before its workers fork,
    instead of every worker starting on numpy and loading numba itself. The PF kernels give the
    numpy path's bits, so this changes the speed only."""
    particle_kernels(work=max(0, int(work)))


def ekf_kernels() -> ModuleType | None:
    """The compiled EKF kernels (:mod:`activetrack.kernels.ekf`) in ``compiled`` mode only,
    else None: they agree with numpy's BLAS products to round-off, not to the bit, so ``auto``
    (which may switch mid-process) keeps the numpy EKF."""
    return _only_compiled("ekf")


def moment_kernels() -> ModuleType | None:
    """The compiled particle moments (:mod:`activetrack.kernels.moments`) in ``compiled``
    mode only, else None (round-off agreement with numpy's BLAS sums, like the EKF's)."""
    return _only_compiled("moments")


def _only_compiled(name: str) -> ModuleType | None:
    if _current_mode() != "compiled":
        return None
    if name not in _compiled_only:
        _compiled_only[name] = importlib.import_module(f"activetrack.kernels.{name}")
    return _compiled_only[name]


def compiled_enabled() -> bool:
    """True when the compiled kernels run now (see the module docstring)."""
    return particle_kernels() is not None


def warm_up() -> dict[str, float]:
    """Compile (or load from numba's cache) every kernel of :data:`KERNEL_MODULES`: seconds
    each, in that order. ImportError without numba."""
    out = {}
    for name in KERNEL_MODULES:
        t0 = time.perf_counter()
        importlib.import_module(name).warm_up()
        out[name] = time.perf_counter() - t0
    return out
