"""Information reduction factor (IRF) for measurements of uncertain origin.

With missed detections and Poisson clutter the Fisher information of a scan is the clutter-free
information scaled by a scalar (Niu, Willett & Bar-Shalom, "Matrix CRLB scaling due to
measurements of uncertain origin", IEEE TSP 49(7), 2001; the "IRF approach" of Hernandez,
Farina & Ristic, IEEE TAES 42(2), 2006)::

    J_Z = q(Pd, lambda, g, n) * H^T R^{-1} H

**Pd is inside q**: multiply by ``q`` only, not by ``Pd`` as well (without clutter
``q = Pd F_{chi2, n+2}(g^2) ~ Pd``: q replaces the pd of :mod:`activetrack.bounds.pcrlb`).

Model (Niu et al. sec. II), in the whitened space: ``nu = R^{-1/2} (z - h(x)) ~ N(0, I_n)``
for the target's measurement; the gate ``G = {|nu| <= g}`` has volume ``V = S_n g^n / n``
(``S_n = 2 pi^{n/2} / Gamma(n/2)``) and holds it with probability ``P_G = F_{chi2, n}(g^2)``;
detection with ``Pd``; false alarms Poisson of mean ``lambda V``, uniform over ``G``, with
``lambda = lambda_z sqrt(det R)`` for a density ``lambda_z`` per unit of z.

Definition (Niu et al. sec. III): with ``m`` measurements in the gate the likelihood is

    p(Z, m | x) = (1 - Pd P_G) mu(m) V^{-m}
                  + Pd mu(m-1) V^{-(m-1)} (1/m) sum_i N(nu_i; 0, I),   mu(k) = Pois(k; lambda V),

whose score is ``H^T R^{-1/2} s``, ``s = Pd sum_i N(nu_i) nu_i / (lambda (1 - Pd P_G) + Pd
sum_j N(nu_j))``; by symmetry ``E[s s^T] = q I`` with

    q = (Pd^2 / n) sum_{m>=1} mu(m-1) V^{-(m-1)} / m
          * int_{G^m} |sum_i N(nu_i) nu_i|^2 / (lambda (1 - Pd P_G) + Pd sum_j N(nu_j))
          dnu_1 .. dnu_m.

Evaluation (exact, no truncation of the Poisson sum): with ``1/D = int_0^inf exp(-t D) dt``
the integrand factorises, the cross terms vanish by symmetry and the sum over ``m`` is an
exponential series::

    q = (Pd^2 / n) int_0^inf A(t) exp(-t lambda (1 - Pd P_G) - lambda C(t)) dt,
    A(t) = int_G N(nu)^2 |nu|^2 exp(-t Pd N(nu)) dnu,
    C(t) = int_G (1 - exp(-t Pd N(nu))) dnu,

both radial, by composite Gauss-Legendre in ``r`` and in ``log t``.
"""

from __future__ import annotations

import hashlib
import importlib
import math
import os
import platform
import sys
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_in_range, require_int, require_nonnegative
from activetrack.stats import chi2_cdf

__all__ = [
    "IRF_TABLE_RANGE",
    "IRF_TABLE_TOLERANCE",
    "MAX_GATE_SIGMAS",
    "information_reduction_factor",
    "information_reduction_factors",
    "irf_cache_clear",
    "irf_cache_info",
]

# Gates wider than this add nothing (P_G = 1 - 1e-20 or closer) and only stretch the quadrature.
MAX_GATE_SIGMAS = 10.0
_MAX_DIM = 3
_GL_NODES = 8

# The tabulated q of :func:`information_reduction_factors`: whitened densities in this range
# (per unit of the whitened space) are interpolated, a cubic spline in log(lambda) on nodes
# _TABLE_PER_DECADE per decade, to within IRF_TABLE_TOLERANCE of the exact integral (tested at
# the midpoints); densities outside it (and 0) take the exact integral.
IRF_TABLE_RANGE = (1e-6, 1e2)
# Where the tables' exact node values are kept between processes (as numba keeps its kernels):
# the same bits as computing them, keyed by everything they depend on (_table_key).
IRF_TABLE_CACHE = Path(__file__).resolve().parent / "__pycache__" / "irf_tables"
IRF_TABLE_TOLERANCE = 1e-6
_TABLE_PER_DECADE = 16
_TABLE_PAD = 4


def information_reduction_factor(
    pd: float, clutter_density: float, gate_sigmas: float, dim: int
) -> float:
    """The IRF ``q`` in [0, 1] of Niu, Willett & Bar-Shalom (2001): ``J_Z = q H^T R^{-1} H``.

    ``pd``: detection probability in [0, 1]; ``clutter_density``: Poisson false-alarm density
    ``lambda >= 0`` per unit of the whitened measurement space (``lambda_z sqrt(det R)``);
    ``gate_sigmas``: gate radius ``g`` in (0, MAX_GATE_SIGMAS] in whitened units (a chi-square
    gate of ``g^2``); ``dim``: measurement dimension (1 bearing, 2 range-bearing / position, 3).

    ``Pd`` is inside ``q``: multiply ``J_Z`` by ``q`` only.  The inputs are rounded (``pd`` and
    ``gate_sigmas`` to 1e-9, ``clutter_density`` to 9 significant digits) to key the cache.
    """
    pd = require_in_range("pd", pd, 0.0, 1.0)
    lam = require_nonnegative("clutter_density", clutter_density)
    g = require_in_range("gate_sigmas", gate_sigmas, 0.0, MAX_GATE_SIGMAS, lo_inclusive=False)
    n = require_int("dim", dim, 1, _MAX_DIM)
    return _irf_core(round(pd, 9), float(f"{lam:.9g}"), round(g, 9), n)


def information_reduction_factors(
    pd: float, clutter_density: ArrayLike, gate_sigmas: float, dim: int
) -> FloatArray:
    """:func:`information_reduction_factor` for an array of whitened densities ``(...)``, e.g.
    ``lambda_z sqrt(det S)`` of a gate on the innovation covariance S, which varies
    continuously with the geometry (and would defeat the cache of the exact form): within
    :data:`IRF_TABLE_RANGE` interpolated from a table of ``q`` over ``log(lambda)`` (cubic,
    within :data:`IRF_TABLE_TOLERANCE` of the exact integral), elsewhere exact. ``(...)``."""
    pd = require_in_range("pd", pd, 0.0, 1.0)
    lam = np.asarray(clutter_density, dtype=float)
    if not (np.isfinite(lam).all() and np.all(lam >= 0.0)):
        raise ValueError("clutter_density must be finite and >= 0")
    g = require_in_range("gate_sigmas", gate_sigmas, 0.0, MAX_GATE_SIGMAS, lo_inclusive=False)
    n = require_int("dim", dim, 1, _MAX_DIM)
    key = (round(pd, 9), round(g, 9), n)
    lo, hi = IRF_TABLE_RANGE
    flat = lam.reshape(-1)
    inside = (flat >= lo) & (flat <= hi)
    out = np.empty(flat.shape)
    out[inside] = _irf_table(*key)(np.log(flat[inside]))
    for i in np.flatnonzero(~inside):
        out[i] = _irf_core(key[0], float(f"{flat[i]:.9g}"), key[1], n)
    return np.clip(out, 0.0, 1.0).reshape(lam.shape)


@lru_cache(maxsize=64)
def _irf_table(pd: float, g: float, n: int) -> Callable[[FloatArray], FloatArray]:
    """The natural cubic spline of exact ``q`` over ``log(lambda)`` on :data:`IRF_TABLE_RANGE`,
    its nodes run on _TABLE_PAD steps past both ends (a natural end's error decays by ~3.7
    per node inwards)."""
    lo, hi = IRF_TABLE_RANGE
    nodes = round(math.log10(hi / lo) * _TABLE_PER_DECADE)
    h = math.log(hi / lo) / nodes
    u = math.log(lo) + h * np.arange(-_TABLE_PAD, nodes + _TABLE_PAD + 1)
    q = _table_nodes(pd, g, n, u)
    # Second derivatives M at the nodes: M_{i-1} + 4 M_i + M_{i+1} = 6 (q_{i-1} - 2 q_i +
    # q_{i+1}) / h^2 inside, M = 0 at both ends.
    m = len(u) - 2
    A = 4.0 * np.eye(m) + np.eye(m, k=1) + np.eye(m, k=-1)
    M = np.zeros(len(u))
    M[1:-1] = np.linalg.solve(A, 6.0 * np.diff(q, 2) / (h * h))

    def spline(x: FloatArray) -> FloatArray:
        i = np.clip(((x - u[0]) // h).astype(int), 0, len(u) - 2)
        t = (x - u[i]) / h
        s = 1.0 - t
        curve = (s**3 - s) * M[i] + (t**3 - t) * M[i + 1]
        return np.asarray(s * q[i] + t * q[i + 1] + h * h / 6.0 * curve, dtype=float)

    return spline


def _table_nodes(pd: float, g: float, n: int, u: FloatArray) -> FloatArray:
    """Exact ``q`` at the nodes ``exp(u)`` of a table: read from :data:`IRF_TABLE_CACHE` when
    this code on this interpreter, numpy and CPU computed them before (the same bits), else
    computed (0.1 s a table; each run's planner needs one per kind of sensor) and stored.
    A cache that cannot be read or written is computed around, never trusted in part."""
    key = _table_key(pd, g, n, u)
    if key is None:
        return _exact_nodes(pd, g, n, u)
    path = IRF_TABLE_CACHE / f"{key}.npy"
    try:
        q = np.load(path, allow_pickle=False)
        if q.dtype == np.float64 and q.shape == u.shape and np.isfinite(q).all():
            return q
    except (OSError, ValueError):
        pass  # not there (or not whole): computed below
    q = _exact_nodes(pd, g, n, u)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        part = path.with_suffix(f".{os.getpid()}.part")
        with open(part, "wb") as f:
            np.save(f, q, allow_pickle=False)
        os.replace(part, path)  # whole or not at all, whoever else writes it
    except OSError:
        pass  # a read-only install: computed each time, as before the cache
    return q


def _exact_nodes(pd: float, g: float, n: int, u: FloatArray) -> FloatArray:
    exact = _irf_core.__wrapped__  # the table's nodes would only crowd the cache
    return np.array([exact(pd, float(math.exp(v)), g, n) for v in u])


def _table_key(pd: float, g: float, n: int, u: FloatArray) -> str | None:
    """What a table's node values depend on: the inputs, the code that computes them (this
    module and ``chi2_cdf``'s) and what runs it (Python and its libm, numpy and the CPU
    features it dispatches to: an AVX-512 exp differs from an AVX2 one in the last bit; scipy,
    whose gammainc ``chi2_cdf`` is). None where numpy's features are unknown: not kept."""
    import scipy

    from activetrack import stats

    h = hashlib.sha256()
    for source in (__file__, stats.__file__):
        h.update(Path(source).read_bytes())
    versions = (sys.version, platform.libc_ver(), np.__version__, scipy.__version__)
    h.update(repr((pd, g, n, versions)).encode())
    features = _numpy_cpu_features()
    if features is None:
        return None
    h.update(repr(features).encode())
    h.update(np.ascontiguousarray(u, dtype=float).tobytes())
    return h.hexdigest()[:32]


def _numpy_cpu_features() -> list[str] | None:
    """The CPU features numpy dispatches to on this machine (from its private table), or None
    where that table is not found (then the tables are not kept)."""
    for name in ("numpy._core._multiarray_umath", "numpy.core._multiarray_umath"):
        try:
            features = importlib.import_module(name).__cpu_features__
        except (ImportError, AttributeError):
            continue
        return sorted(k for k, on in features.items() if on)
    return None


def irf_cache_info() -> Any:
    """``functools.lru_cache`` statistics of the cached IRF core."""
    return _irf_core.cache_info()


def irf_cache_clear() -> None:
    """Empty the IRF caches in memory (the tables of :func:`information_reduction_factors`
    too; their nodes on disk, IRF_TABLE_CACHE, stay: they are the same bits)."""
    _irf_core.cache_clear()
    _irf_table.cache_clear()
    _time_integrals.cache_clear()


@lru_cache(maxsize=1)
def _legendre() -> tuple[FloatArray, FloatArray]:
    """The _GL_NODES-point Gauss-Legendre rule on [-1, 1] (an eigenproblem: ~0.1 ms a call)."""
    return np.polynomial.legendre.leggauss(_GL_NODES)


def _gauss_legendre(lo: float, hi: float, n_panels: int) -> tuple[FloatArray, FloatArray]:
    """Composite Gauss-Legendre nodes and weights on ``[lo, hi]``."""
    x, w = _legendre()
    edges = np.linspace(lo, hi, n_panels + 1)
    half = 0.5 * np.diff(edges)
    mid = 0.5 * (edges[1:] + edges[:-1])
    nodes = (mid[:, None] + half[:, None] * x[None, :]).ravel()
    weights = (half[:, None] * w[None, :]).ravel()
    return nodes, weights


@lru_cache(maxsize=4096)
def _irf_core(pd: float, lam: float, g: float, n: int, resolution: float = 1.0) -> float:
    """``q`` for validated, rounded inputs; ``resolution`` scales the quadrature grids."""
    if pd == 0.0:
        return 0.0
    surface = 2.0 * math.pi ** (n / 2) / math.gamma(n / 2)  # S_n: dnu = S_n r^{n-1} dr
    volume = surface * g**n / n
    p_gate = chi2_cdf(g * g, n)  # F_{chi2, n}(g^2)
    n0 = (2.0 * math.pi) ** (-n / 2)  # N(0; 0, I_n)

    # Scaled time s = t Pd N(0), integrated in u = log s.  Below s_lo the integrand is ~ s
    # (30 e-folds are negligible); above s_hi, exp(-s phi) < e^-50 everywhere in the gate.
    clutter_rate = lam * (volume + (1.0 - pd * p_gate) / (pd * n0))
    u_lo = -30.0 - max(0.0, math.log(clutter_rate)) if clutter_rate > 0.0 else -30.0
    s, wu, a_int, c_int = _time_integrals(g, n, resolution, u_lo)
    log_damp = -s * lam * (1.0 - pd * p_gate) / (pd * n0) - lam * surface * c_int
    # dt = ds / (Pd N0) and N^2 = N0^2 phi^2:  q = Pd N0 S_n / n * int s a(s) damp(s) du
    total = float(np.sum(wu * s * a_int * np.exp(log_damp)))
    q = pd * n0 * surface * total / n
    return float(min(max(q, 0.0), 1.0))


@lru_cache(maxsize=64)
def _time_integrals(
    g: float, n: int, resolution: float, u_lo: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The radial integrals ``A`` and ``C`` of :func:`_irf_core` (module docstring, up to
    constant factors) at the nodes ``s = exp(u)`` of the ``log t`` grid from ``u_lo``, with
    ``s`` and the grid's weights. They depend on neither ``Pd`` nor ``lambda``: every density
    whose clutter rate is <= 1 (u_lo = -30, the lower half of a table's nodes) shares them,
    which makes a table three times as fast (the exp over the (u, r) grid is the work)."""
    # Radial grid: exp(-s phi(r)) switches over a width ~1/r, so panels of <= 0.125 sigma.
    r, wr = _gauss_legendre(0.0, g, max(4, math.ceil(8.0 * g * resolution)))
    phi = np.exp(-0.5 * r * r)  # N(r) / N(0)
    u_hi = 0.5 * g * g + math.log(50.0)
    u, wu = _gauss_legendre(u_lo, u_hi, max(8, math.ceil(2.0 * (u_hi - u_lo) * resolution)))
    s = np.exp(u)
    minus_s_phi = -s[:, None] * phi[None, :]  # -t Pd N(nu), shape (u, r)
    a_int = (np.exp(minus_s_phi) * (phi * phi * r ** (n + 1) * wr)[None, :]).sum(axis=1)
    c_int = (-np.expm1(minus_s_phi) * (r ** (n - 1) * wr)[None, :]).sum(axis=1)
    for a in (s, wu, a_int, c_int):
        a.flags.writeable = False  # shared by the cache
    return s, wu, a_int, c_int
