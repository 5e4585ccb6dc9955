"""Tracking filters that scenario files can name: each registered once, with a factory::

    def make_ukf(model, x0, P0, config, rng):
        return UnscentedFilter(model, x0, P0)

    register_filter("ukf", make_ukf, description="unscented Kalman filter (filterpy)")

The factory gets the tracker's motion model, the prior ``x0`` ``(n,)``, ``P0`` ``(n, n)`` (and
their time if it takes the keyword ``t0``: tracks started after epoch 0), the scenario's
``tracker:`` block (:class:`activetrack.scenarios.schema.TrackerConfig`) and the tracker's
generator ``rng`` (the filter's only randomness), and returns a
:class:`~activetrack.filters.measurement.TrackingFilter`. Then ``tracker: {filter: ukf}``
loads, the tracker builds it through :func:`make_filter` and the ROS graph accepts its tracks.
``particle_based=True`` declares a posterior of weighted ``particles`` ``(N, n)`` and
``weights`` ``(N,)`` (as ``pf``): the particle options and rules apply, and the planner draws
its samples from it. See docs/extending.md, "A filter".
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from activetrack.arraytypes import FloatArray
from activetrack.filters.measurement import TrackingFilter
from activetrack.models.base import MotionModel

__all__ = [
    "FilterFactory",
    "FilterKind",
    "ParticlePosterior",
    "built_in_filters",
    "filter_kind",
    "filter_names",
    "make_filter",
    "register_filter",
    "unregister_filter",
]

# factory(model, x0 (n,), P0 (n, n), config (the scenario's tracker block), rng) -> filter
FilterFactory = Callable[
    [MotionModel, FloatArray, FloatArray, Any, np.random.Generator], TrackingFilter
]

_NAME = re.compile(r"[a-z][a-z0-9_]{0,31}")
# What every built filter must offer (TrackingFilter's members).
_MEMBERS = ("time", "mean", "cov", "predict", "update", "step")


@runtime_checkable
class ParticlePosterior(Protocol):
    """A filter whose posterior is a weighted particle set (``particle_based`` filters)."""

    @property
    def particles(self) -> np.ndarray:
        """The particles, ``(N, n)``."""
        ...

    @property
    def weights(self) -> np.ndarray:
        """Their normalised weights, ``(N,)``."""
        ...


@dataclass(frozen=True)
class FilterKind:
    """One registered filter: its name, factory and what the scenario rules need to know."""

    name: str
    factory: FilterFactory
    particle_based: bool = False
    description: str = ""
    # optional: k filters at once, factory_many(model, X0 (k, n), P0 (k, n, n), config, rng,
    # t0=...) -> the k filters factory would build, in order (the tracker starts a scan's
    # tracks together with it)
    factory_many: Callable[..., Sequence[TrackingFilter]] | None = None


_FILTERS: dict[str, FilterKind] = {}
_BUILT_IN: set[str] = set()


def _one_of(names: tuple[str, ...]) -> str:
    shown = [repr(n) for n in names]
    return shown[0] if len(shown) == 1 else f"{', '.join(shown[:-1])} or {shown[-1]}"


def register_filter(
    name: str,
    factory: FilterFactory,
    *,
    particle_based: bool = False,
    description: str = "",
    replace: bool = False,
    factory_many: Callable[..., Sequence[TrackingFilter]] | None = None,
) -> FilterKind:
    """Make the filter ``name`` available to scenario files (module docstring). ValueError for a
    bad or built-in name, a factory that is not callable, or a name registered before (unless
    ``replace``; registering the same factory again is a no-op)."""
    if not (isinstance(name, str) and _NAME.fullmatch(name)):
        raise ValueError(
            f"filter name must be 1-32 lower-case letters, digits and '_', starting with a "
            f"letter, got {name!r}"
        )
    if not callable(factory):
        raise ValueError(f"filter {name!r}: factory must be callable, got {factory!r}")
    if factory_many is not None and not callable(factory_many):
        raise ValueError(f"filter {name!r}: factory_many must be callable, got {factory_many!r}")
    entry = FilterKind(name, factory, bool(particle_based), str(description), factory_many)
    old = _FILTERS.get(name)
    if old is not None and old == entry:
        return old
    if name in _BUILT_IN or (old is not None and not replace):
        raise ValueError(f"filter {name!r} is registered already; unregister_filter it first")
    _FILTERS[name] = entry
    return entry


def unregister_filter(name: str) -> None:
    """Remove a registered filter (not a built-in one); scenario files naming it no longer
    load."""
    if name in _BUILT_IN or name not in _FILTERS:
        raise ValueError(f"filter {name!r} is not a registered, removable filter")
    del _FILTERS[name]


def filter_names() -> tuple[str, ...]:
    """The registered filter names, in registration order."""
    return tuple(_FILTERS)


def built_in_filters() -> tuple[str, ...]:
    """The built-in filter names (``ekf``, ``pf``: registered by :mod:`activetrack.filters`)."""
    return tuple(name for name in _FILTERS if name in _BUILT_IN)


def filter_kind(name: str) -> FilterKind:
    """The registration of ``name``; ValueError listing the registered names otherwise."""
    found = _FILTERS.get(name) if isinstance(name, str) else None
    if found is None:
        raise ValueError(f"tracker.filter: must be one of {_one_of(filter_names())}, got {name!r}")
    return found


def _takes_t0(factory: FilterFactory) -> bool:
    try:
        return "t0" in inspect.signature(factory).parameters
    except (TypeError, ValueError):  # a callable without a signature
        return False


def make_filter(
    name: str,
    model: MotionModel,
    x0: FloatArray,
    P0: FloatArray,
    config: Any,
    rng: np.random.Generator,
    t0: float = 0.0,
) -> TrackingFilter:
    """Build the filter ``name`` and check its :class:`TrackingFilter` members (and
    ``particles``, ``weights`` if ``particle_based``). ``t0`` goes to a factory that takes it;
    a nonzero one is refused for one that does not."""
    entry = filter_kind(name)
    if _takes_t0(entry.factory):
        built = entry.factory(model, x0, P0, config, rng, t0=t0)  # type: ignore[call-arg]
    elif t0 == 0.0:
        built = entry.factory(model, x0, P0, config, rng)
    else:
        raise ValueError(
            f"filter {name!r}: its factory takes no keyword t0, so it cannot start a track at "
            f"t0 = {t0} (a track from a detection after epoch 0); add t0=0.0 to the factory"
        )
    missing = [m for m in _MEMBERS if not hasattr(built, m)]
    if entry.particle_based and not isinstance(built, ParticlePosterior):
        missing += [m for m in ("particles", "weights") if not hasattr(built, m)]
    if missing:
        raise ValueError(
            f"filter {name!r}: its factory returned a {type(built).__name__} without "
            f"{missing} (the TrackingFilter members, activetrack.filters.measurement)"
        )
    return built


def _register_built_in(name: str, factory: FilterFactory, **kwargs: Any) -> None:
    register_filter(name, factory, **kwargs)
    _BUILT_IN.add(name)
