"""PCRLB manoeuvre planning (:func:`plan`): one manoeuvre per controllable platform at epoch k
from the target's information state (J_k and Monte Carlo samples at k), and a report.

Planning modes (Hernandez sec. 3.2 and footnote 2) differ only in the belief passed in:

- open loop: J_0 = C_0^{-1} and samples from the prior, then :func:`advance_belief` after each
  decision (J by eq. 3 along the chosen paths, samples through the known dynamics);
- renewal: each decision starts from the tracker's posterior, :meth:`TargetBelief.from_particles`
  (PF) or :meth:`TargetBelief.from_gaussian` (EKF).

The samples at k are pushed through the dynamics (eq. 2) to k+1..k+R; ``rng`` adds the process
noise (None: noise-free) and seeds the evolutionary search.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from activetrack.angles import wrap_angle
from activetrack.arraytypes import ArrayLike
from activetrack.bounds.costs import position_determinant, trace_cost
from activetrack.bounds.pcrlb import (
    covariance_bound,
    gaussian_samples,
    pcrlb_step,
    propagate_samples,
)
from activetrack.checks import require_finite, require_positive, require_psd, require_spd
from activetrack.kernels import prefer_kernels
from activetrack.planning.costs import FleetInformation, platform_information
from activetrack.planning.criteria import PCRLB, get_criterion
from activetrack.planning.horizons import SearchSettings
from activetrack.planning.manoeuvre import PlannerPlatform
from activetrack.planning.multisensor import coordinate_platforms
from activetrack.planning.objective import InformationTerm, Objective
from activetrack.planning.searches import check_integer

__all__ = [
    "PlanReport",
    "PlanResult",
    "PlanSettings",
    "PlannedManoeuvre",
    "PlannerPlatform",
    "TargetBelief",
    "advance_belief",
    "plan",
]


# Candidates per platform and decision from which the planner takes the compiled kernels even
# before numba is loaded (activetrack.kernels): two-step quadrant search (34^2 = 1,156) and
# beyond, the grid; not the single-step searches (34, 41 or 5 candidates).
HEAVY_DECISION = 1000


@dataclass(frozen=True)
class TargetBelief:
    """Target information state at the decision epoch: Fisher information J ``(4, 4)`` (pv)
    and equally weighted pv samples ``(M, 4)`` for the Monte Carlo J_Z (eq. 8)."""

    J: np.ndarray
    samples: np.ndarray

    def __post_init__(self) -> None:
        J = require_spd("belief.J", self.J)
        if J.shape != (4, 4):
            raise ValueError(f"belief.J must be (4, 4) (pv information), got {J.shape}")
        X = require_finite("belief.samples", self.samples)
        if X.ndim != 2 or X.shape[1] != 4 or X.shape[0] < 1:
            raise ValueError(f"belief.samples must have shape (M >= 1, 4), got {X.shape}")
        object.__setattr__(self, "J", J)
        object.__setattr__(self, "samples", X)

    @classmethod
    def from_gaussian(
        cls, mean: ArrayLike, cov: ArrayLike, n_samples: int, rng: np.random.Generator
    ) -> TargetBelief:
        """J = cov^{-1} (eq. 4) and ``n_samples`` draws from N(mean, cov): the prior (open loop)
        or an EKF posterior (renewal)."""
        cov = require_spd("cov", cov)
        return cls(covariance_bound(cov), gaussian_samples(mean, cov, n_samples, rng))

    @classmethod
    def from_particles(
        cls,
        particles: ArrayLike,
        weights: ArrayLike | None = None,
        n_samples: int | None = None,
        rng: np.random.Generator | int | None = None,
    ) -> TargetBelief:
        """Renewal from a PF posterior: J = (weighted particle covariance)^{-1} and
        ``n_samples`` particles drawn by weight (all particles if None and unweighted)."""
        X = require_finite("particles", particles)
        if X.ndim != 2 or X.shape[1] != 4 or X.shape[0] < 2:
            raise ValueError(f"particles must have shape (N >= 2, 4), got {X.shape}")
        N = X.shape[0]
        w = np.full(N, 1.0 / N) if weights is None else require_finite("weights", weights)
        if w.shape != (N,) or np.any(w < 0) or not w.sum() > 0:
            raise ValueError(f"weights must be ({N},), non-negative, with a positive sum")
        w = w / w.sum()
        mean = w @ X
        D = X - mean
        P = (D.T * w) @ D
        cov = require_spd("particles (their weighted covariance)", 0.5 * (P + P.T))
        if n_samples is None and weights is None:
            samples = X
        else:
            if n_samples is None:
                n_samples = N
            if int(n_samples) < 1:
                raise ValueError(f"n_samples must be >= 1, got {n_samples!r}")
            rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
            samples = X[rng.choice(N, size=int(n_samples), p=w)]
        return cls(covariance_bound(cov), samples)


@dataclass(frozen=True)
class PlanSettings:
    """criterion: one that applies to PCRLB planning (:mod:`activetrack.planning.criteria`:
    ``"b_k"``, eq. 10, ``"trace"``, ``"det_pos"`` or a registered one); horizon R >= 1;
    search: see :class:`SearchSettings`; max_sensor_iterations: sec. 4.1 footnote 4."""

    criterion: str = "b_k"
    horizon: int = 1
    search: SearchSettings = field(default_factory=SearchSettings)
    max_sensor_iterations: int = 10

    def __post_init__(self) -> None:
        get_criterion(self.criterion, PCRLB, what="settings.criterion")
        for name in ("horizon", "max_sensor_iterations"):
            check_integer(f"settings.{name}", getattr(self, name))
        if not isinstance(self.search, SearchSettings):
            raise ValueError("settings.search must be a SearchSettings")


@dataclass(frozen=True)
class PlannedManoeuvre:
    """The manoeuvre of one controllable platform for the leg k -> k+1, and its ``plan`` ``(R,
    2)`` of (dpsi, v') over the horizon (only row 0 is flown)."""

    platform_id: str
    heading_change: float
    speed_change: float
    heading: float
    speed: float
    next_pv: np.ndarray
    plan: np.ndarray


@dataclass(frozen=True)
class PlanReport:
    """Predicted costs at k+1 with the chosen manoeuvres (``predicted``: b_k, bound_x, bound_y,
    trace, det_pos), the horizon objective, evaluations, multi-platform passes, wall time."""

    criterion: str
    search: str
    horizon: int
    objective: float
    predicted: dict[str, float]
    evaluations: int
    iterations: int
    converged: bool
    wall_time_s: float

    @property
    def cost_names(self) -> tuple[str, ...]:
        return ("objective", *self.predicted)

    @property
    def predicted_costs(self) -> tuple[float, ...]:
        return (self.objective, *self.predicted.values())


@dataclass(frozen=True)
class PlanResult:
    """Manoeuvres of the controllable platforms (input order), the report and the predicted
    information J_{k+1} ``(4, 4)`` with everyone's chosen manoeuvre."""

    manoeuvres: tuple[PlannedManoeuvre, ...]
    report: PlanReport
    J_next: np.ndarray

    def manoeuvre(self, platform_id: str) -> PlannedManoeuvre:
        for m in self.manoeuvres:
            if m.platform_id == platform_id:
                return m
        raise ValueError(f"platform_id {platform_id!r} has no planned manoeuvre")


def _check_dynamics(F: ArrayLike, Q: ArrayLike, dt: float) -> tuple[np.ndarray, np.ndarray, float]:
    F = require_finite("F", F)
    if F.shape != (4, 4):
        raise ValueError(f"F must be (4, 4) (linear pv dynamics, eq. 2), got {F.shape}")
    Q = require_psd("Q", Q)
    if Q.shape != (4, 4):
        raise ValueError(f"Q must be (4, 4), got {Q.shape}")
    return F, Q, require_positive("dt", dt)


def _predicted_costs(J: np.ndarray) -> dict[str, float]:
    P = covariance_bound(J)
    bx, by = math.sqrt(P[0, 0]), math.sqrt(P[2, 2])
    return {
        "b_k": max(bx, by),
        "bound_x": bx,
        "bound_y": by,
        "trace": float(trace_cost(P)),
        "det_pos": float(position_determinant(P)),
    }


def _manoeuvres(
    platforms: Sequence[PlannerPlatform], plans: Sequence[np.ndarray | None], dt: float
) -> tuple[PlannedManoeuvre, ...]:
    """The first manoeuvre of each controllable platform's plan, flown for one leg."""
    manoeuvres = []
    for p, pl in zip(platforms, plans, strict=True):
        if pl is None:
            continue
        dpsi, v = float(pl[0, 0]), float(pl[0, 1])
        heading0, speed0 = p.heading_and_speed
        heading = float(wrap_angle(heading0 + dpsi))
        next_pv = np.array(
            [
                p.pv[0] + v * math.cos(heading) * dt,
                v * math.cos(heading),
                p.pv[2] + v * math.sin(heading) * dt,
                v * math.sin(heading),
            ]
        )
        manoeuvres.append(
            PlannedManoeuvre(p.platform_id, dpsi, v - speed0, heading, v, next_pv, pl)
        )
    return tuple(manoeuvres)


def plan(
    platforms: Sequence[PlannerPlatform],
    belief: TargetBelief,
    settings: PlanSettings,
    *,
    F: np.ndarray,
    Q: np.ndarray,
    dt: float,
    rng: np.random.Generator | None = None,
) -> PlanResult:
    """Choose the manoeuvre of every controllable platform at epoch k.

    Args:
        platforms: the platforms at epoch k (controllable ones carry limits).
        belief: J_k and target samples at epoch k.
        settings: criterion, horizon R (1: eq. 11; 2: DP eq. 13-15; R: eq. 16), search.
        F, Q: target dynamics over one interval (eq. 2), ``(4, 4)``; dt: the interval T (s).
        rng: process noise for the sample propagation and the evolutionary search's seed.

    Returns:
        :class:`PlanResult`. Raises ValueError naming the bad argument.
    """
    start = time.perf_counter()
    platforms = list(platforms)
    if not platforms or not all(isinstance(p, PlannerPlatform) for p in platforms):
        raise ValueError("platforms must be a non-empty sequence of PlannerPlatform")
    ids = [p.platform_id for p in platforms]
    if len(set(ids)) != len(ids):
        raise ValueError(f"platforms: platform ids must be unique, got {ids}")
    if not isinstance(belief, TargetBelief):
        raise ValueError("belief must be a TargetBelief")
    if not isinstance(settings, PlanSettings):
        raise ValueError("settings must be a PlanSettings (see scenarios.build.plan_settings)")
    if rng is not None and not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator or None, got {type(rng)}")
    F, Q, dt = _check_dynamics(F, Q, dt)
    R = int(settings.horizon)
    samples = propagate_samples(belief.samples, F, Q, R, rng)  # (R, M, 4) at k+1..k+R
    fleet = FleetInformation(platforms, F, Q, samples)
    # One target, one term: the criterion of the bound summed over the legs (eq. 11, 15-16).
    objective = Objective((InformationTerm(get_criterion(settings.criterion, PCRLB)),))
    # Heavy decisions pay for numba's start-up: take the compiled kernels (activetrack.kernels).
    with prefer_kernels(settings.search.evaluations_per_platform(R) >= HEAVY_DECISION):
        result = coordinate_platforms(
            platforms,
            fleet,
            objective,
            belief.J[None],
            dt,
            settings.search,
            R,
            settings.max_sensor_iterations,
            rng,
        )
        J = fleet.bound_information(belief.J)  # (R, 4, 4) with everybody's plans
        value = objective.along([J_r[None] for J_r in J])  # one track
    manoeuvres = _manoeuvres(platforms, result.plans, dt)
    report = PlanReport(
        criterion=settings.criterion,
        search=settings.search.search,
        horizon=R,
        objective=value,
        predicted=_predicted_costs(J[0]),
        evaluations=result.evaluations,
        iterations=result.iterations,
        converged=result.converged,
        wall_time_s=time.perf_counter() - start,
    )
    return PlanResult(manoeuvres, report, J[0])


def advance_belief(
    belief: TargetBelief,
    platforms_next: Sequence[PlannerPlatform],
    F: np.ndarray,
    Q: np.ndarray,
    rng: np.random.Generator | None = None,
) -> TargetBelief:
    """Open-loop step (Hernandez sec. 3.2): samples to k+1 through eq. 2 (noise from ``rng``,
    none if None) and J_{k+1} by eq. 3 with every platform's sensors at its pv at k+1."""
    F, Q, _ = _check_dynamics(F, Q, 1.0)
    X = propagate_samples(belief.samples, F, Q, 1, rng)[0]
    J_Z = sum(platform_information(p.sensors, p.pv, X) for p in platforms_next)
    return TargetBelief(pcrlb_step(belief.J, F, Q, J_Z), X)
