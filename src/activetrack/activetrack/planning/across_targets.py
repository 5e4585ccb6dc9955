"""Planning across targets (``MultiTargetPlanner``, a strategy of
:class:`activetrack.planning.decision.Planner`): platform manoeuvres against every confirmed
track, and steerable beams assigned to tracks.

Each sensor is a :class:`activetrack.models.clutter.ClutteredSensor`: J_Z with the information
reduction factor q in place of pd and its field of view applied (Hernandez eq. 8, IRF of Niu,
Willett & Bar-Shalom 2001); a beam (``beam_width``) observes only the track it serves. Cost of
a confirmed track, ``planner.cost``:

- ``pcrlb``: ``planner.criterion`` of the bound at k+1..k+R, renewal from the track (Hernandez
  eq. 3, footnote 2), J_Z by Monte Carlo (eq. 8) over the track's particles or ``mc_samples``
  Gaussian draws pushed through the dynamics (eq. 2);
- ``mre``: ``planner.criterion`` of Ramdaras eq. 23 with q as detection factor at the CV
  prediction F^{r+1} x (``planner.targets.clutter_gate: innovation``: q of the tracker's gate
  on S = H P H^T + R, P the covariance the look updates, at the candidate's position). A
  beam, pointed before the epoch's measurements, holds the target with probability
  ``assignment.beam_coverage``, lowered for each unsuccessful look since the track's last hit
  (``assignment.MissedLooks``: otherwise the beams keep looking at a lost track's empty
  prediction), and raised again as the prediction widens past the spread it had
  at those looks (the target may have come back into the part they emptied; otherwise a track
  left after a few misses is never looked at again while it drifts).

Tracks combine by ``planner.targets.aggregate`` (``worst`` plus ``TIE_BREAK`` times the sum
during the search, or ``weighted_sum``). Manoeuvres: platforms in turn, the others on their
current plans (Hernandez sec. 4.1, ``multisensor.coordinate_platforms``), each searching its R
legs; pcrlb sums over the legs (eq. 15-16), mre takes leg R. During the search a beam serves
its previous track if still confirmed, else the nearest. Under ``weighted_sum`` and a
deterministic search, platforms whose sensors serve no common track are searched
independently (the sum over tracks separates; ``coordinate_platforms`` says why the plans are
the same), and a platform's search computes the tracks its sensors do not serve once, not per
candidate (mre: their first leg once per decision). Beams, after the manoeuvres, from the
planned k+1 positions (``planner.targets.assignment``): ``mre`` optimal assignment of eq. 23
costs, ``random`` (balanced), ``nearest``; a beam points at its track's predicted position. No
confirmed track: every beam sweeps one ``beam_width`` per epoch from its platform's heading.

``planner.targets.objective: gospa`` replaces the criterion by the tracks' expected GOSPA
(:mod:`activetrack.planning.expected_gospa`): manoeuvres scored by a rollout over
``planner.horizon`` epochs (:mod:`activetrack.planning.gospa_rollout`, a search one leg
deep), "every platform holds course" kept when it scores no worse than the plans found, and
beams (``assignment: mre``) assigned on the tracks' expected GOSPA at k+1.

``planner.targets.surveillance`` (with ``gospa``, or random beams): search versus track. The
planner keeps the intensity of targets not yet detected over the region, which every look
depletes (:mod:`activetrack.planning.search_intensity`); each beam's search pointings (and
tentative tracks) are columns of its assignment next to the tracks, valued in the same GOSPA
units, and the rollout scores every candidate manoeuvre, hold course too, with the search its
beams may make from where it takes them (:class:`activetrack.planning.gospa_rollout.
FirstLegSearch`). A tentative track the looks just started weighs the PMBM's existence of a
new target at its cell (:func:`activetrack.planning.search_intensity.birth_odds`), not the
tracker's fixed initial one. The intensity is state a restarted planner does not rebuild (it
starts empty again).

Random draws, all from the planner's generator, in order: the tracks' Gaussian samples and
process noise (pcrlb), the evolutionary search, the random assignment.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, cast

import numpy as np

from activetrack.angles import wrap_angle
from activetrack.bounds.mre import mre_update
from activetrack.bounds.pcrlb import (
    covariance_bound,
    gaussian_samples,
    predicted_information,
    propagate_samples,
)
from activetrack.checks import symmetrize
from activetrack.data import (
    BeamCommand,
    Command,
    Decision,
    PlanReportData,
    PlatformSnapshot,
    TrackEstimate,
    TrackSet,
)
from activetrack.models.clutter import CLUTTER_GATES, ClutteredSensor, starts_tracks
from activetrack.models.fov import sector_coverage
from activetrack.planning.assignment import (
    NO_MISSES,
    MissedLooks,
    assign_beams,
    assign_beams_gospa,
    beam_coverage,
    footprint_pointing,
    nearest_assignment,
    random_assignment,
)
from activetrack.planning.criteria import POSITIONING, get_criterion
from activetrack.planning.decision import DecisionContext, DecisionPart
from activetrack.planning.expected_gospa import (
    GospaWeights,
    hit_probability,
    managed_split,
    position_spread,
)
from activetrack.planning.gospa_rollout import (
    FirstLegSearch,
    GospaRollout,
    Look,
    in_view,
    look_factors,
    straight_on,
)
from activetrack.planning.horizons import SearchSettings
from activetrack.planning.manoeuvre import PlannerPlatform, PlatformLimits, hold_course
from activetrack.planning.multisensor import coordinate_platforms
from activetrack.planning.objective import (
    TIE_BREAK,
    CovarianceTerm,
    ExpectedGospaTerm,
    InformationTerm,
    Objective,
    TrackAggregate,
    aggregate_costs,
)
from activetrack.planning.search_intensity import (
    Surveillance,
    UndetectedIntensity,
    birth_odds,
    footprint,
    footprints,
    search_bearings,
    search_value,
)
from activetrack.planning.selection import TargetPrediction, expected_update
from activetrack.planning.strategies import LinearDynamics
from activetrack.tracking.management import EXISTENCE_INIT

__all__ = ["AcrossTargetsSettings", "MultiTargetPlanner", "ScenePlatform"]


@dataclass(frozen=True)
class _Sensor:
    sensor_id: str
    platform: int  # index into the scenario's platforms
    model: ClutteredSensor
    q: float  # the IRF, cached

    @property
    def steerable(self) -> bool:
        return self.model.beam_width is not None

    def detection(
        self,
        x: np.ndarray,
        pv: np.ndarray,
        P: np.ndarray | None = None,
        missed: MissedLooks = NO_MISSES,
        gate: np.ndarray | None = None,
    ) -> np.ndarray:
        """Eq. 23's detection factor q I_r I_fov ``(...)`` for a target at x seen from pvs
        ``(..., 4)``; a beam times its coverage of ``P`` (None: on target) after ``missed``.
        q of the gate on ``gate`` (default ``P``; the sensor's ``clutter_gate``), else of R."""
        inside = np.asarray(self.model.in_range(x, pv), dtype=float)
        G = P if gate is None else gate
        q = self.q if G is None else self.model.planned_information_factor(x, pv, G)
        d = q * inside * in_view(self.model, x, pv)
        if self.steerable and P is not None:
            c = beam_coverage(cast(float, self.model.beam_width), x, P, pv)
            d = d * missed.after(c, P)
        return d

    def detections(
        self, xs: np.ndarray, pv: np.ndarray, Ps: np.ndarray, missed: Sequence[MissedLooks]
    ) -> np.ndarray:
        """:meth:`detection` of T tracks at once, ``xs`` ``(T, 4)``, ``Ps`` ``(T, 4, 4)`` (also
        the gate), from one pv ``(4,)``: ``(T,)``, the same numbers as track by track (the
        same operations on each track's rows)."""
        inside = np.asarray(self.model.in_range(xs, pv), dtype=float)
        q = self.model.planned_information_factor(xs, pv, Ps)
        d = q * inside * in_view(self.model, xs, pv)
        if not self.steerable:
            return np.asarray(d, dtype=float)
        c = beam_coverage(cast(float, self.model.beam_width), xs, Ps, pv)
        after = np.array(c, dtype=float)  # c itself for a track without misses
        for t, m in enumerate(missed):
            if m.factor < 1.0:
                after[t] = m.after(c[t], Ps[t])
        return np.asarray(d * after, dtype=float)

    def hit(self, x: np.ndarray, pv: np.ndarray, P: np.ndarray, missed: MissedLooks) -> float:
        """The chance Pd I_r I_fov c that this sensor at ``pv`` detects a target N(x, P)."""
        inside, c = look_factors(self.model, x, pv, P, missed)
        return float(self.model.pd) * float(inside) * float(c)

    def hits(self, xs: np.ndarray, pv: np.ndarray, Ps: np.ndarray) -> np.ndarray:
        """:meth:`hit` of K targets N(xs, Ps), ``(K, 4)`` and ``(K, 4, 4)``, from one pv
        ``(4,)`` without misses: ``(K,)``, the same numbers as target by target."""
        inside, c = look_factors(self.model, xs, pv, Ps, NO_MISSES)
        return float(self.model.pd) * inside * c


@dataclass
class _PcrlbStage:
    """Hernandez eq. 3 for every track (a :class:`HorizonStage`): J ``(..., T, 4, 4)``;
    ``fixed`` ``(R, T, 4, 4)`` the other platforms' J_Z; ``own`` the optimised platform's
    sensors and the tracks each serves; ``samples`` per track ``(R, M_t, 4)``."""

    F: np.ndarray
    Q: np.ndarray
    samples: list[np.ndarray]
    fixed: np.ndarray
    own: tuple[tuple[ClutteredSensor, np.ndarray], ...]

    def prepare(self, J: np.ndarray, level: int) -> np.ndarray:
        return predicted_information(J, self.F, self.Q)  # once per J_prev

    def advance(self, J_pred: np.ndarray, level: int, pv: np.ndarray) -> np.ndarray:
        J_Z = np.zeros((*pv.shape[:-1], len(self.samples), 4, 4))
        for t, X in enumerate(self.samples):
            for sensor, serves in self.own:
                if serves[t]:
                    J_Z[..., t, :, :] += sensor.fisher_information(X[level], pv)
        return J_pred + self.fixed[level] + J_Z


@dataclass
class _MreStage:
    """Ramdaras eq. 23 for every track (a :class:`HorizonStage`): P_{k+1+r|k+r} ``(..., T, 4,
    4)``; ``x`` ``(R, T, 4)`` CV predictions; ``fixed[r][t]`` the other platforms' sensors
    serving track t with their pvs at leg r; ``own`` as in :class:`_PcrlbStage`.

    A track no sensor of ``own`` serves (not in :attr:`moved`) has the same state under every
    candidate: its leg is computed once per level, from the first candidate's copy of its
    state (the same matrices, so the same numbers as per candidate), and copied."""

    F: np.ndarray
    Q: np.ndarray
    x: np.ndarray
    fixed: list[list[list[tuple[_Sensor, np.ndarray]]]]
    own: tuple[tuple[_Sensor, np.ndarray], ...]
    missed: tuple[MissedLooks, ...]
    # a held track's first leg by the looks at it (other platforms' sensors and their pvs),
    # shared by the stages of one decision: they start from the same state
    first_legs: dict[tuple, np.ndarray] = field(default_factory=dict)
    held: dict[int, np.ndarray] = field(default_factory=dict)  # level -> (H, 4, 4)

    def __post_init__(self) -> None:
        T = self.x.shape[1]
        self.serving = [[sensor for sensor, serves in self.own if serves[t]] for t in range(T)]
        self.moved = np.array([bool(s) for s in self.serving], dtype=bool)
        self.held_tracks = np.flatnonzero(~self.moved)

    def prepare(self, P: np.ndarray, level: int) -> np.ndarray:
        return P if level == 0 else symmetrize(P)

    def advance(self, P: np.ndarray, level: int, pv: np.ndarray) -> np.ndarray:
        out = np.empty((*pv.shape[:-1], self.x.shape[1], 4, 4))
        for t in np.flatnonzero(self.moved):
            out[..., t, :, :] = self._leg(P[..., t, :, :], level, int(t), pv)
        if len(self.held_tracks):
            if level not in self.held:
                first = P[(0,) * (P.ndim - 3)]  # (T, 4, 4): every candidate's copy alike
                held = self.F @ first[self.held_tracks] @ self.F.T + self.Q  # no look
                for h, t in enumerate(self.held_tracks):
                    if self.fixed[level][t]:
                        held[h] = self._held_leg(first[t], level, int(t))
                self.held[level] = held
            out[..., self.held_tracks, :, :] = self.held[level]
        return out

    def _held_leg(self, P0: np.ndarray, level: int, t: int) -> np.ndarray:
        """:meth:`_leg` of a track ``own`` does not serve; at level 0 (from the decision's
        state0) once per decision for the same looks."""
        if level != 0:
            return self._leg(P0, level, t, None)
        key = (t, *((s.sensor_id, at.tobytes()) for s, at in self.fixed[0][t]))
        if key not in self.first_legs:
            self.first_legs[key] = self._leg(P0, level, t, None)
        return self.first_legs[key]

    def _leg(self, P0: np.ndarray, level: int, t: int, pv: np.ndarray | None) -> np.ndarray:
        """Track t's P_{k+2+level|k+1+level} from P_{k+1+level|k+level} ``P0`` ``(..., 4,
        4)``: the other platforms' sensors' expected updates, then own's at ``pv``."""
        x, Pt = self.x[level][t], P0
        looks = list(self.fixed[level][t])  # the other platforms' sensors first
        if pv is not None:
            looks += [(sensor, pv) for sensor in self.serving[t]]
        for sensor, at in looks:
            d = sensor.detection(x, at, P0, self.missed[t], gate=Pt)  # gated as updated
            Pt = mre_update(Pt, sensor.model.jacobian(x, at), sensor.model.R, d)
        return self.F @ Pt @ self.F.T + self.Q


@dataclass(frozen=True)
class _Pointings:
    """A beam's search pointings: ``bearings`` ``(J,)``, ``values`` ``(J,)`` [GOSPA^p], the
    tentative track each looks at (-1: the region's intensity) ``track_ids`` ``(J,)``."""

    bearings: np.ndarray
    values: np.ndarray
    track_ids: np.ndarray


@dataclass(frozen=True)
class _SearchScene:
    """What every beam's search pointings share in one decision (:meth:`MultiTargetPlanner.
    _search_options`): the cells no track covers ``free`` ``(N,)``, the tentative tracks
    that may hold a target not yet tracked (``track_ids``) with their predictions ``x``
    ``(K, 4)``, ``P`` ``(K, 4, 4)`` and existences ``exist`` ``(K,)``."""

    tracks: Sequence[TrackEstimate]
    free: np.ndarray
    track_ids: list[int]
    x: np.ndarray
    P: np.ndarray
    exist: np.ndarray


@dataclass
class _Epoch:
    """One decision's working set (a :class:`PlatformStages` of the coordinator): CV
    predictions ``x`` ``(R, T, 4)`` (mre) or samples (pcrlb), missed looks ``(T,)``, which
    tracks each sensor serves ``(S, T)``, the platforms' paths ``(R, 4)``."""

    planner: MultiTargetPlanner
    epoch: int
    platforms: list[PlannerPlatform]
    tracks: tuple[TrackEstimate, ...]
    predictions: list[TargetPrediction]
    weights: np.ndarray
    missed: tuple[MissedLooks, ...]
    serves: np.ndarray
    x: np.ndarray | None = None
    samples: list[np.ndarray] = field(default_factory=list)
    paths: dict[int, np.ndarray] = field(default_factory=dict)
    plans: dict[int, np.ndarray] = field(default_factory=dict)  # controllable platforms' (R, 2)
    evaluations: int = 0
    first_legs: dict[tuple, np.ndarray] = field(default_factory=dict)  # see _MreStage
    # beam sensor -> (bearing, tentative track id or -1) when it searches
    search: dict[int, tuple[float, int]] = field(default_factory=dict)
    # beam sensor -> its bearing when pointed at the tracks it holds (pointing "footprint")
    pointing: dict[int, float] = field(default_factory=dict)

    def follow(self, i: int, path: np.ndarray) -> None:
        self.paths[i] = path

    def stage(self, j: int | None) -> _PcrlbStage | _MreStage | GospaRollout:
        return self.planner._stage(self, j)


@dataclass(frozen=True)
class AcrossTargetsSettings:
    """The scenario's ``planner:`` section as this planner reads it; ``search`` None: no
    platform is steered; ``aggregate`` and ``assignment`` from ``planner.targets``."""

    cost_kind: str
    criterion: str
    horizon: int
    search: SearchSettings | None
    mc_samples: int
    max_iterations: int
    aggregate: str
    assignment: str
    objective: str = "criterion"
    gospa: GospaWeights | None = None
    surveillance: Surveillance | None = None
    pointing: str = "track"
    # the tracker's thresholds of existence that end a confirmed track, from a detection /
    # from a prior (``tracker.tracks``; 0: never): the gospa objective counts the ending
    existence_terminate: float = 0.0
    existence_terminate_prior: float = 0.0
    # the IRF of a planned look: of R, or of the tracker's gate on S = H P H^T + R
    # (:meth:`activetrack.models.clutter.ClutteredSensor.planned_information_factor`)
    clutter_gate: str = "measurement"

    def __post_init__(self) -> None:
        if self.objective not in ("criterion", "gospa"):
            raise ValueError(f"objective must be 'criterion' or 'gospa', got {self.objective!r}")
        if self.clutter_gate not in CLUTTER_GATES:
            raise ValueError(
                f"clutter_gate must be one of {CLUTTER_GATES}, got {self.clutter_gate!r}"
            )
        if self.pointing not in ("track", "footprint"):
            raise ValueError(f"pointing must be 'track' or 'footprint', got {self.pointing!r}")
        if self.pointing == "footprint" and self.objective != "criterion":
            raise ValueError("pointing: 'footprint' needs objective 'criterion'")
        if self.objective == "gospa" and self.gospa is None:
            raise ValueError("gospa: the objective 'gospa' needs GOSPA's c, p and alpha")


@dataclass(frozen=True)
class ScenePlatform:
    """A platform as this planner knows it: its ``(sensor id, sensor)`` pairs and its limits
    when the planner steers it (None: it holds course)."""

    platform_id: str
    sensors: tuple[tuple[str, ClutteredSensor], ...]
    controllable: bool = False
    limits: PlatformLimits | None = None


class MultiTargetPlanner:
    """Manoeuvres and beam pointings against every confirmed track (module docstring); draws
    only from its own ``rng``."""

    def __init__(
        self,
        platforms: Sequence[ScenePlatform],
        dynamics: LinearDynamics,
        settings: AcrossTargetsSettings,
        rng: np.random.Generator,
    ):
        self.rng = rng
        self.dynamics = dynamics
        self.dt = dynamics.dt
        self.platform_ids = tuple(p.platform_id for p in platforms)
        self.sensors = tuple(
            _Sensor(sid, i, gated, gated.information_factor)
            for i, p in enumerate(platforms)
            for sid, model in p.sensors
            for gated in [replace(model, clutter_gate=settings.clutter_gate)]
        )
        self.controllable = tuple(p.controllable for p in platforms)
        self.limits = tuple(p.limits for p in platforms)
        self.cost_kind = settings.cost_kind
        self.criterion = get_criterion(settings.criterion)
        if settings.assignment == "mre" and not self.criterion.applies_to(POSITIONING):
            raise ValueError(
                f"planner.criterion must apply to MRE positioning with planner.targets."
                f"assignment 'mre', got {settings.criterion!r}"
            )
        steering = any(lim is not None for lim in self.limits)
        self.search = settings.search if steering else None
        self.horizon = settings.horizon if steering else 1
        self.gospa = settings.gospa if settings.objective == "gospa" else None
        if self.gospa is not None:  # a rollout of R legs behind a search one leg deep
            self.lookahead, self.horizon = settings.horizon, 1
        self.settings = settings
        self.last_track: dict[str, int] = {}  # beam sensor id -> track id it served last
        self.last_bearing: dict[str, float] = {}
        # track id -> (M since its last hit, its hits then, the last look's coverage and the
        # spread then); the looks for the next epoch: track id -> (hits, misses,
        # prod (1 - pd I_r), coverage, spread).
        self.miss_factor: dict[int, tuple[float, int, float, float]] = {}
        self.looks: dict[int, tuple[int, int, float, float, float]] = {}
        # Search versus track: the undetected-target intensity (with the gospa objective or
        # random beams) and the looks commanded for the next epoch (sensor, beam bearing).
        searching = settings.objective == "gospa" or settings.assignment == "random"
        self.undetected = (
            UndetectedIntensity(settings.surveillance, self.dt)
            if settings.surveillance is not None and searching
            else None
        )
        self.pending_looks: list[tuple[int, float | None]] = []
        self.all_tracks: tuple[TrackEstimate, ...] = ()
        self._search_scene: _SearchScene | None = None  # this decision's, once computed
        # the odds e / kappa per cell of this epoch's looks, and per track from a detection
        # the factor from the tracker's initial odds to the birth odds of its first detection
        self.odds_now = np.zeros(0)
        self.birth_factor: dict[int, float] = {}
        # sensors whose one detection, a position of two components, may start a track
        self.births_from = tuple(
            starts_tracks(s.model) and np.shape(s.model.R)[0] == 2 for s in self.sensors
        )

    def decide(self, context: DecisionContext) -> DecisionPart:
        """:meth:`plan` as a :class:`~activetrack.planning.decision.PlannerStrategy` part."""
        d = self.plan(context.epoch, context.tracks, list(context.platforms.values()))
        evaluations = d.report.evaluations if d.report is not None else 0
        return DecisionPart(
            d.commands, report=d.report, evaluations=evaluations, extra=d.extra, beams=d.beams
        )

    def plan(self, epoch: int, tracks: TrackSet, platforms: Sequence[PlatformSnapshot]) -> Decision:
        """Commands for the leg epoch -> epoch+1, beam pointings for epoch+1, the report."""
        start = time.perf_counter()
        snaps = {s.platform_id: s for s in platforms}
        missing = [pid for pid in self.platform_ids if pid not in snaps]
        if missing:
            raise ValueError(f"platforms: states missing for {missing}")
        planners = [
            PlannerPlatform(
                pid,
                snaps[pid].pv,
                tuple(s.model for s in self.sensors if s.platform == i),
                self.limits[i],
                heading=snaps[pid].heading,
                speed=snaps[pid].speed,
            )
            for i, pid in enumerate(self.platform_ids)
        ]
        self._note_looks(tracks)
        self.all_tracks = tracks.tracks  # tentative ones too: their cells are not searched
        self._search_scene = None
        if self.undetected is not None:
            self._deplete(snaps)
            self._note_births(tracks)
        if not tracks.confirmed:
            return self._sweep(epoch, planners, start, tracks)
        ep = self._epoch(epoch, planners, tracks.confirmed)
        objective = self._manoeuvres(ep)
        next_pv = np.stack([ep.paths[j][0] for j in range(len(planners))])
        self._assign(ep, next_pv)
        costs = self._track_costs(ep, next_pv)
        return self._decision(ep, next_pv, costs, objective, time.perf_counter() - start)

    def _note_looks(self, tracks: TrackSet) -> None:
        """Last epoch's beam looks: a track looked at without a hit takes the factor
        prod (1 - pd I_r) of those beams and their coverage and spread (:class:`MissedLooks`);
        a track with a new hit starts afresh (M = 1)."""
        now = {t.track_id: t for t in tracks.tracks}
        factors = {
            i: miss for i, miss in self.miss_factor.items() if i in now and now[i].hits <= miss[1]
        }
        for i, (hits, misses, fail, coverage, spread) in self.looks.items():
            t = now.get(i)
            if t is not None and t.hits <= hits and t.misses > misses:
                M = factors.get(i, (1.0, hits, 0.0, 0.0))[0]
                factors[i] = (M * fail, hits, coverage, spread)
        self.miss_factor, self.looks = factors, {}

    def _missed(self, track_id: int) -> MissedLooks:
        """The unsuccessful looks at a track since its last hit."""
        M, _, coverage, spread = self.miss_factor.get(track_id, (1.0, 0, 0.0, 0.0))
        return MissedLooks(M, coverage, spread)

    def _deplete(self, snaps: dict[str, PlatformSnapshot]) -> None:
        """The undetected intensity at this epoch: last epoch's births, then the looks just
        made (commanded last epoch) from where the platforms are now."""
        u = cast(UndetectedIntensity, self.undetected)
        u.predict()
        self.odds_now = np.full(len(u.xy), np.nan)  # NaN: no look with birth odds saw it
        for i, bearing in self.pending_looks:
            s = self.sensors[i]
            pv = snaps[self.platform_ids[s.platform]].pv
            seen = footprint(s.model, u.xy, pv, bearing)
            if self.births_from[i]:  # the look that best explains a detection
                odds = birth_odds(s.model, u, pv, seen)
                self.odds_now = np.where(seen, np.fmax(self.odds_now, odds), self.odds_now)
            u.look(seen, float(s.model.pd))
        self.pending_looks = []

    def _note_births(self, tracks: TrackSet) -> None:
        """Tracks from one detection made now: the planner's existence of each is the PMBM's
        new Bernoulli, e / (e + kappa) at its cell (:func:`birth_odds`), in place of the
        tracker's fixed initial existence; the factor between their odds stays with the track
        (its later hits and misses move the tracker's odds as they would the planner's). A
        track outside the region (beyond a cell) has odds 0; one the planner did not see
        born (hits > 1 when first seen: a restarted planner) or in a cell no look of a
        sensor measuring a position of two components saw (:func:`birth_odds` needs one: a
        range-rate radar's) keeps the tracker's existence."""
        u = cast(UndetectedIntensity, self.undetected)
        init = EXISTENCE_INIT / (1.0 - EXISTENCE_INIT)
        live = {t.track_id for t in tracks.tracks}
        self.birth_factor = {i: f for i, f in self.birth_factor.items() if i in live}
        for t in tracks.tracks:
            if t.track_id in self.birth_factor or t.origin or t.status == "confirmed":
                continue
            if t.hits > 1:
                self.birth_factor[t.track_id] = 1.0
                continue
            cell = int(u.cell_of([[t.mean[0], t.mean[2]]])[0])
            odds = float(self.odds_now[cell]) if cell >= 0 else 0.0
            self.birth_factor[t.track_id] = 1.0 if math.isnan(odds) else odds / init

    def _tentative_existence(self, t: TrackEstimate) -> float:
        """A tentative track's existence as the planner weighs it (:meth:`_note_births`)."""
        f = self.birth_factor.get(t.track_id, 1.0)
        if t.existence >= 1.0 or math.isinf(f):
            return 1.0 if f > 0.0 else t.existence
        odds = t.existence / (1.0 - t.existence) * f
        return odds / (1.0 + odds)

    def _ahead(self, pv: np.ndarray) -> np.ndarray:
        """A pv ``(4,)`` one epoch on at constant velocity (holding course)."""
        return np.array([pv[0] + self.dt * pv[1], pv[1], pv[2] + self.dt * pv[3], pv[3]])

    @staticmethod
    def _near_held(xy: np.ndarray, held: np.ndarray, k: GospaWeights | None) -> np.ndarray:
        """Whether each position ``(T, 2)`` lies within c of one of ``held`` ``(H, 2)``."""
        if held.shape[0] == 0 or k is None:
            return np.zeros(xy.shape[0], dtype=bool)
        d2 = ((xy[:, None, :] - held[None, :, :]) ** 2).sum(axis=-1)
        return np.any(d2 <= k.c * k.c, axis=1)

    def _pending(self, i: int, bearing: float | None) -> None:
        """Sensor i looks at the next epoch (at ``bearing`` for a beam): it depletes then."""
        if self.undetected is not None:
            self.pending_looks.append((i, bearing))

    def _search_options(
        self, tracks: Sequence[TrackEstimate], beams: list[int], pvs: np.ndarray
    ) -> list[_Pointings]:
        """Each beam's search pointings from its planned pv ``(B, 4)``, valued in GOSPA^p
        for the look-ahead's epochs: one beam width apart over the cells no track covers
        (within c of a track's prediction; :func:`search_value`), and one at each tentative
        track, the target it may hold found with its existence r times the chance of a hit
        (r Pd I c_beam c^p / alpha per epoch: confirming it needs looks at it)."""
        u = cast(UndetectedIntensity, self.undetected)
        scene = self._search_scene
        if scene is None or scene.tracks is not tracks:  # the candidates of one decision share it
            scene = self._search_scene = self._scene_for_search(tracks)
        k = self.settings.gospa
        cardinality = k.cardinality if k is not None else 1.0
        epochs = self.lookahead if self.gospa is not None else 1
        out = []
        D = u.intensity  # the beams' common data: summed over the layers once
        for i, pv in zip(beams, pvs, strict=True):
            s = self.sensors[i]
            bearings = search_bearings(u.xy, pv, cast(float, s.model.beam_width))
            seen = footprints(s.model, u.xy, pv, bearings) & scene.free
            values = search_value(D, seen, float(s.model.pd), cardinality, epochs)
            at = [math.atan2(x[2] - pv[2], x[0] - pv[0]) for x in scene.x]
            found = scene.exist * s.hits(scene.x, pv, scene.P)
            out.append(
                _Pointings(
                    np.concatenate([bearings, at]),
                    np.concatenate([values, found * cardinality * epochs]),
                    np.array([-1] * len(bearings) + scene.track_ids),
                )
            )
        return out

    def _scene_for_search(self, tracks: Sequence[TrackEstimate]) -> _SearchScene:
        """:class:`_SearchScene` of ``tracks`` at the next epoch (their CV predictions)."""
        u = cast(UndetectedIntensity, self.undetected)
        F = self.dynamics.F
        Q = self.dynamics.Q
        ahead = [(t, F @ t.mean[:4], F @ t.cov[:4, :4] @ F.T + Q) for t in tracks]
        xy = np.array([[x[0], x[2]] for _, x, _ in ahead]).reshape(-1, 2)
        k = self.settings.gospa
        held = xy[[t.status == "confirmed" for t, _, _ in ahead]]
        tentative = [  # one within c of a confirmed track is that track's target again
            a
            for a, near in zip(ahead, self._near_held(xy, held, k), strict=True)
            if a[0].status != "confirmed" and not near
        ]
        return _SearchScene(
            tracks,
            u.uncovered(xy, k.c if k is not None else 0.0),
            [t.track_id for t, _, _ in tentative],
            np.array([x for _, x, _ in tentative]).reshape(-1, 4),
            np.array([P for _, _, P in tentative]).reshape(-1, 4, 4),
            np.array([self._tentative_existence(t) for t, _, _ in tentative], dtype=float),
        )

    def _epoch(
        self, epoch: int, planners: list[PlannerPlatform], tracks: tuple[TrackEstimate, ...]
    ) -> _Epoch:
        d, R = self.dynamics, self.horizon if self.gospa is None else self.lookahead
        predictions = TargetPrediction.from_posteriors(
            [t.mean for t in tracks], [t.cov for t in tracks], d.F, d.Q
        )
        ep = _Epoch(
            self,
            epoch,
            planners,
            tracks,
            predictions,
            np.array([t.priority for t in tracks], dtype=float),
            tuple(self._missed(t.track_id) for t in tracks),
            self._serving_now(planners, tracks, predictions),
        )
        if self.cost_kind == "pcrlb":
            for t in tracks:
                X = t.samples
                if X is None:
                    X = gaussian_samples(t.mean, t.cov, self.settings.mc_samples, self.rng)
                ep.samples.append(propagate_samples(X, d.F, d.Q, R, self.rng))
        if self.cost_kind != "pcrlb" or self.gospa is not None:
            x = [np.stack([p.x for p in predictions])]  # x_{k+1+r|k} = F^r x_{k+1|k}
            for _ in range(1, R):
                x.append(x[-1] @ d.F.T)
            ep.x = np.stack(x)
        return ep

    def _serving_now(
        self,
        planners: list[PlannerPlatform],
        tracks: tuple[TrackEstimate, ...],
        predictions: list[TargetPrediction],
    ) -> np.ndarray:
        """``(S, T)``: every track for a fixed sensor; for a beam its previous track if still
        confirmed, else the nearest one to its platform now; pointed at footprints, the tracks
        its last bearing holds from its platform now, if any."""
        ids = [t.track_id for t in tracks]
        xy = np.array([[p.x[0], p.x[2]] for p in predictions])
        serves = np.ones((len(self.sensors), len(tracks)), dtype=bool)
        for i, s in enumerate(self.sensors):
            if s.steerable:
                pv = planners[s.platform].pv
                bearing = self.last_bearing.get(s.sensor_id)
                if self.settings.pointing == "footprint" and bearing is not None:
                    theta = np.arctan2(xy[:, 1] - pv[2], xy[:, 0] - pv[0])
                    width = cast(float, s.model.beam_width)
                    serves[i] = np.abs(wrap_angle(theta - bearing)) <= 0.5 * width
                    if serves[i].any():
                        continue
                last = self.last_track.get(s.sensor_id)
                t = ids.index(last) if last in ids else int(nearest_assignment(pv[::2], xy)[0])
                serves[i] = np.arange(len(tracks)) == t
        return serves

    def _state0(self, ep: _Epoch) -> np.ndarray:
        if self.cost_kind == "pcrlb":
            return np.stack([covariance_bound(t.cov) for t in ep.tracks])
        return np.stack([p.P for p in ep.predictions])

    def _stage(self, ep: _Epoch, j: int | None) -> _PcrlbStage | _MreStage | GospaRollout:
        """The stage of platform ``j`` being optimised, every other platform on its path
        (``j`` None: all fixed, for the objective of the plans)."""
        own = [(s, ep.serves[i]) for i, s in enumerate(self.sensors) if s.platform == j]
        others = [(s, ep.serves[i]) for i, s in enumerate(self.sensors) if s.platform != j]
        d = self.dynamics
        if self.gospa is not None:
            L = self.lookahead
            looks = tuple(
                Look(s.model, serves, straight_on(ep.paths[s.platform][0], L, self.dt))
                for s, serves in others
            )
            search = None
            if self.undetected is not None:  # the looks first, then own (as the rollout)
                order = [i for i, s in enumerate(self.sensors) if s.platform != j]
                order += [i for i, s in enumerate(self.sensors) if s.platform == j]
                values = tuple(
                    self._search_value(i) if self.sensors[i].steerable else None for i in order
                )
                search = FirstLegSearch(values, ep.weights)
            return GospaRollout(
                self.cost_kind,
                d.F,
                d.Q,
                cast(np.ndarray, ep.x),
                ep.samples,
                looks,
                tuple((s.model, serves) for s, serves in own),
                ep.missed,
                self._existence(ep),
                self.gospa,
                self.dt,
                search,
            )
        if self.cost_kind == "pcrlb":
            fixed = np.zeros((self.horizon, len(ep.tracks), 4, 4))
            for s, serves in others:
                path = ep.paths[s.platform]
                for t in np.flatnonzero(serves):
                    for r in range(self.horizon):
                        fixed[r, t] += s.model.fisher_information(ep.samples[t][r], path[r])
            own_models = tuple((s.model, serves) for s, serves in own)
            return _PcrlbStage(d.F, d.Q, ep.samples, fixed, own_models)
        updates: list[list[list[tuple[_Sensor, np.ndarray]]]] = [
            [[] for _ in ep.tracks] for _ in range(self.horizon)
        ]
        for s, serves in others:
            for r in range(self.horizon):
                for t in np.flatnonzero(serves):
                    updates[r][t].append((s, ep.paths[s.platform][r]))
        return _MreStage(
            d.F, d.Q, cast(np.ndarray, ep.x), updates, tuple(own), ep.missed, ep.first_legs
        )

    def _objective(self, ep: _Epoch, tie_break: float) -> Objective:
        """The tracks' aggregate criterion of J (pcrlb, eq. 15-16) or P (mre)."""
        if self.gospa is not None:  # with a region, its row (priority 1: already GOSPA^p)
            region = np.ones(1 if self.undetected is not None else 0)
            return Objective((ExpectedGospaTerm(np.concatenate([ep.weights, region])),))
        tracks = TrackAggregate(self.settings.aggregate, ep.weights, tie_break)
        if self.cost_kind == "pcrlb":
            return Objective((InformationTerm(self.criterion, tracks),))
        return Objective((CovarianceTerm(self.criterion, cast(np.ndarray, ep.x), tracks),))

    def _manoeuvres(self, ep: _Epoch) -> float:
        """Sets ``ep.plans`` and ``ep.paths`` (Hernandez sec. 4.1); returns the objective of
        everybody's plans without tie-break."""
        state0 = self._state0(ep)
        result = coordinate_platforms(
            ep.platforms,
            ep,
            self._objective(ep, TIE_BREAK),
            state0,
            self.dt,
            self.search,
            self.horizon,
            self.settings.max_iterations,
            self.rng,
            self._supports(ep),
        )
        ep.plans = {j: plan for j, plan in enumerate(result.plans) if plan is not None}
        ep.evaluations = result.evaluations
        if self.gospa is not None:
            return self._against_hold_course(ep, state0)
        # Every platform on its path: the states along the legs (no candidate of anyone).
        stage, state, states = ep.stage(None), state0, []
        dummy = np.zeros((1, 1, 4))
        for r in range(self.horizon):
            state = stage.advance(stage.prepare(state, r), r, dummy)
            states.append(state)
        return self._objective(ep, 0.0).along(states)

    def _supports(self, ep: _Epoch) -> list[np.ndarray | None] | None:
        """Per platform the tracks ``(T,)`` its candidates change, the ones its sensors serve
        during the search; None (every platform interacts with every other) under the gospa
        rollout, the worst track (not a sum over tracks) or a search drawing random numbers
        (searching a platform again draws again)."""
        if (
            self.gospa is not None
            or self.settings.aggregate != "weighted_sum"
            or self.search is None
            or self.search.search == "evolution"
        ):
            return None
        platform = np.array([s.platform for s in self.sensors], dtype=int)
        return [ep.serves[platform == j].any(axis=0) for j in range(len(ep.platforms))]

    def _plans_objective(self, ep: _Epoch, state0: np.ndarray) -> float:
        """The objective of every platform on its path in ``ep.paths`` (one evaluation)."""
        stage = ep.stage(None)
        return self._objective(ep, 0.0).along([stage.advance(state0, 0, np.zeros((1, 1, 4)))])

    def _against_hold_course(self, ep: _Epoch, state0: np.ndarray) -> float:
        """ "Every platform holds course" is a candidate too: kept unless the plans found
        score better (the coordinator's passes start from it but may leave it for a plan that
        is better only for the platform that searched). Returns the objective kept."""
        found = self._plans_objective(ep, state0)
        if not ep.plans:
            return found
        paths = dict(ep.paths)
        for j in ep.plans:
            p = ep.platforms[j]
            hold = hold_course(p.heading_and_speed[1], cast(PlatformLimits, p.limits), 1)
            ep.follow(j, p.path(self.dt, 1, hold))
        held = self._plans_objective(ep, state0)
        if held <= found:
            ep.plans = {}
            return held
        ep.paths = paths
        return found

    def _search_value(self, i: int) -> Callable[[np.ndarray], np.ndarray]:
        """pvs ``(..., 4)`` -> the GOSPA^p beam i's best search pointing saves from each
        ``(...)`` (the most valuable of its :meth:`_search_options`: a platform whose beam
        sees a smaller bearing span of the region covers more of it per look)."""

        def value(pvs: np.ndarray) -> np.ndarray:
            pvs = np.asarray(pvs, dtype=float)
            flat = pvs.reshape(-1, 4)
            options = self._search_options(self.all_tracks, [i] * len(flat), flat)
            return np.array([np.max(o.values) for o in options]).reshape(pvs.shape[:-1])

        return value

    def _assign(self, ep: _Epoch, next_pv: np.ndarray) -> None:
        """Every beam to one confirmed track at the planned k+1 positions: ``ep.serves``."""
        beams = [i for i, s in enumerate(self.sensors) if s.steerable]
        if not beams:
            return
        T = len(ep.tracks)
        pvs = np.stack([next_pv[self.sensors[i].platform] for i in beams])
        options = (
            self._search_options(self.all_tracks, beams, pvs)
            if self.undetected is not None
            else None
        )
        if options is not None and self.settings.assignment == "random":
            # the fair random baseline: uniform over the tracks and the beam's search pointings
            picks = np.array([int(self.rng.integers(T + len(o.bearings))) for o in options])
        elif self.settings.assignment == "random":
            picks = random_assignment(len(beams), T, self.rng)
        elif self.settings.assignment == "nearest":
            xy = np.array([[p.x[0], p.x[2]] for p in ep.predictions])
            picks = nearest_assignment(pvs[:, ::2], xy)
        elif self.gospa is not None:
            picks = self._assign_gospa(ep, next_pv, beams, pvs, options)
        elif self.settings.pointing == "footprint":
            self._point_footprints(ep, next_pv, beams, pvs)
            return
        else:
            picks = assign_beams(
                self._fixed_updates(ep, next_pv),
                [self.sensors[i].model for i in beams],
                pvs,
                self._detections(ep, beams, pvs),
                self.criterion.name,
                ep.weights,
                self.settings.aggregate,
            )
        for b, (i, t) in enumerate(zip(beams, picks, strict=True)):
            ep.serves[i] = np.arange(T) == t
            if t >= T:
                o = cast(list, options)[b]
                ep.search[i] = (float(o.bearings[t - T]), int(o.track_ids[t - T]))

    def _detections(self, ep: _Epoch, beams: list[int], pvs: np.ndarray) -> np.ndarray:
        """Each beam's detection factor of each track at k+1 from its pv ``(B, 4)``: ``(B,
        T)`` (:meth:`_Sensor.detections`)."""
        xs = np.stack([p.x for p in ep.predictions])
        Ps = np.stack([p.P for p in ep.predictions])
        return np.stack(
            [
                self.sensors[i].detections(xs, pv, Ps, ep.missed)
                for i, pv in zip(beams, pvs, strict=True)
            ]
        )

    def _point_footprints(
        self, ep: _Epoch, next_pv: np.ndarray, beams: list[int], pvs: np.ndarray
    ) -> None:
        """Beam bearings crediting every track a beam holds
        (:func:`~activetrack.planning.assignment.footprint_pointing`): ``ep.pointing`` and, in
        ``ep.serves``, the tracks inside each beam."""
        preds = ep.predictions
        bearings, holds = footprint_pointing(
            self._fixed_updates(ep, next_pv),
            [self.sensors[i].model for i in beams],
            pvs,
            np.array(
                [
                    [self.sensors[i].detection(p.x, pv, gate=p.P) for p in preds]
                    for i, pv in zip(beams, pvs, strict=True)
                ]
            ),
            ep.missed,
            self.criterion.name,
            ep.weights,
        )
        for b, i in enumerate(beams):
            ep.serves[i] = holds[b]
            ep.pointing[i] = float(bearings[b])

    def _terminate(self, ep: _Epoch) -> np.ndarray:
        """The tracker's threshold of existence that ends each track ``(T,)`` (its own for a
        track from a prior)."""
        s = self.settings
        return np.array(
            [s.existence_terminate_prior if t.origin else s.existence_terminate for t in ep.tracks]
        )

    @staticmethod
    def _existence(ep: _Epoch) -> np.ndarray:
        """The tracks' probabilities of existence ``(T,)`` (the tracker's IPDA)."""
        return np.array([t.existence for t in ep.tracks], dtype=float)

    def _fixed_hits(self, ep: _Epoch, next_pv: np.ndarray) -> np.ndarray:
        """Each track's chance of a hit at k+1 from the fixed (non-steerable) sensors ``(T,)``."""
        fixed = [s for s in self.sensors if not s.steerable]
        return np.array(
            [
                hit_probability([s.hit(p.x, next_pv[s.platform], p.P, ep.missed[t]) for s in fixed])
                for t, p in enumerate(ep.predictions)
            ],
            dtype=float,
        )

    def _assign_gospa(
        self,
        ep: _Epoch,
        next_pv: np.ndarray,
        beams: list[int],
        pvs: np.ndarray,
        options: list[_Pointings] | None = None,
    ) -> np.ndarray:
        """The beams' tracks minimising the tracks' expected GOSPA at k+1
        (:func:`~activetrack.planning.assignment.assign_beams_gospa`); with ``options`` (each
        beam's search pointings and values) also the search columns: a pick T + j is the
        beam's pointing j."""
        preds = ep.predictions
        search, offsets = None, np.zeros(1, dtype=int)
        if options is not None:  # beam b's pointings are columns offsets[b]..offsets[b+1]
            sizes = [len(o.values) for o in options]
            offsets = np.concatenate([[0], np.cumsum(sizes)])
            search = np.full((len(beams), int(offsets[-1])), np.nan)
            for b, o in enumerate(options):
                search[b, offsets[b] : offsets[b + 1]] = o.values
        pairs = [(self.sensors[i], pv) for i, pv in zip(beams, pvs, strict=True)]
        picks = assign_beams_gospa(
            self._fixed_updates(ep, next_pv),
            [s.model for s, _ in pairs],
            pvs,
            np.array(
                [
                    [s.detection(p.x, pv, p.P, ep.missed[t]) for t, p in enumerate(preds)]
                    for s, pv in pairs
                ]
            ),
            np.array(
                [
                    [s.hit(p.x, pv, p.P, ep.missed[t]) for t, p in enumerate(preds)]
                    for s, pv in pairs
                ]
            ),
            (
                self._fixed_hits(ep, next_pv),
                np.array([float(position_spread(p.P)) for p in preds]),
                self._existence(ep),
            ),
            cast(GospaWeights, self.gospa),
            ep.weights,
            search,
            self._terminate(ep),
        )
        if options is None:
            return picks
        T = len(preds)  # a search pick T + j of all columns: T + j' of its own beam's pointings
        return np.array([t if t < T else t - int(offsets[b]) for b, t in enumerate(picks)])

    @staticmethod
    def _expected_update(
        p: TargetPrediction, sensors: list[_Sensor], next_pv: np.ndarray, missed: MissedLooks
    ) -> np.ndarray:
        """P_{k+1|k} with the expected updates (eq. 23's bracket) of ``sensors`` at their
        platforms' planned pvs, :meth:`_Sensor.detection` as the detection factors."""
        if not sensors:
            return p.P
        pvs = np.stack([next_pv[s.platform] for s in sensors])
        factors = [
            float(s.detection(p.x, pv, p.P, missed)) for s, pv in zip(sensors, pvs, strict=True)
        ]
        return expected_update(p.P, p.x, [s.model for s in sensors], pvs, detection=factors)

    def _fixed_updates(self, ep: _Epoch, next_pv: np.ndarray) -> list[TargetPrediction]:
        """Each track's prediction with the fixed (non-steerable) sensors' expected updates."""
        fixed = [s for s in self.sensors if not s.steerable]
        if not fixed:
            return list(ep.predictions)
        return [
            p.with_covariance(self._expected_update(p, fixed, next_pv, NO_MISSES))
            for p in ep.predictions
        ]

    def _track_costs(self, ep: _Epoch, next_pv: np.ndarray) -> np.ndarray:
        """Each track's cost at k+1 with the chosen manoeuvres and beams ``(T,)``."""
        out = np.empty(len(ep.tracks))
        done = np.zeros(len(ep.tracks), dtype=bool)
        if self.gospa is None and self.cost_kind != "pcrlb" and not self.criterion.needs_state:
            # The tracks no sensor serves at once: P_{k+1|k} itself, the same numbers.
            done = np.asarray(~ep.serves.any(axis=0), dtype=bool)
            if done.any():
                preds = [p for p, free in zip(ep.predictions, done, strict=True) if free]
                P, F, Q = (np.stack([getattr(p, a) for p in preds]) for a in ("P", "F", "Q"))
                P_next = F @ P @ np.swapaxes(F, -1, -2) + Q
                out[done] = self.criterion.of_covariance(P_next, None)
        for t, (track, p) in enumerate(zip(ep.tracks, ep.predictions, strict=True)):
            if done[t]:
                continue
            serving = [s for i, s in enumerate(self.sensors) if ep.serves[i, t]]
            if self.gospa is not None:
                out[t] = self._gospa_cost(ep, t, serving, next_pv)
            elif self.cost_kind == "pcrlb":
                J = predicted_information(covariance_bound(track.cov), p.F, p.Q)
                for s in serving:
                    J = J + s.model.fisher_information(ep.samples[t][0], next_pv[s.platform])
                out[t] = float(self.criterion.of_information(J))
            else:
                P = self._expected_update(p, serving, next_pv, ep.missed[t])
                out[t] = float(self.criterion.of_covariance(p.F @ P @ p.F.T + p.Q, p.x))
        return out

    def _gospa_cost(self, ep: _Epoch, t: int, serving: list[_Sensor], next_pv: np.ndarray) -> float:
        """Track t's expected GOSPA^p at k+1 with the sensors ``serving`` it (eq. 23's update)."""
        p, w = ep.predictions[t], cast(GospaWeights, self.gospa)
        P = self._expected_update(p, serving, next_pv, ep.missed[t])
        q = hit_probability([s.hit(p.x, next_pv[s.platform], p.P, ep.missed[t]) for s in serving])
        r, tau = self._existence(ep)[t], self._terminate(ep)[t]
        return float(managed_split(r, q, position_spread(p.P), position_spread(P), w, tau).sum())

    def _commands(self, ep_platforms: list[PlannerPlatform], epoch: int, plans: dict) -> list:
        """A command per controllable platform: its plan's first manoeuvre, else hold course."""
        commands = []
        for j, p in enumerate(ep_platforms):
            if j in plans:
                heading, speed = p.heading_and_speed
                dpsi, v = float(plans[j][0, 0]), float(plans[j][0, 1])
                psi = float(wrap_angle(heading + dpsi))
                commands.append(Command(p.platform_id, epoch, dpsi, v - speed, psi, v))
            elif self.controllable[j]:
                commands.append(Command(p.platform_id, epoch, 0.0, 0.0))
        return commands

    def _decision(
        self, ep: _Epoch, next_pv: np.ndarray, costs: np.ndarray, objective: float, wall: float
    ) -> Decision:
        beams = []
        for i, s in enumerate(self.sensors):
            if not s.steerable:
                self._pending(i, None)
                continue
            if i in ep.search:
                bearing, track_id = ep.search[i]
                beams.append(BeamCommand(s.sensor_id, ep.epoch, bearing, track_id))
                self.last_bearing[s.sensor_id] = bearing
                self.last_track.pop(s.sensor_id, None)
                self._pending(i, bearing)
                continue
            pv = next_pv[s.platform]
            held = np.flatnonzero(ep.serves[i])
            at = {int(u): self._bearing(ep, int(u), pv) for u in held}  # each held track's
            if i in ep.pointing:  # the beam's centre; its track the held one nearest to it
                bearing = ep.pointing[i]
                off = [abs(wrap_angle(at[int(u)] - bearing)) for u in held]
                t = int(held[int(np.argmin(off))]) if len(held) else -1
            else:
                t = int(held[0])
                bearing = at[t]
            track_id = ep.tracks[t].track_id if t >= 0 else -1
            beams.append(BeamCommand(s.sensor_id, ep.epoch, bearing, track_id))
            if t >= 0:
                self.last_track[s.sensor_id] = track_id
            else:
                self.last_track.pop(s.sensor_id, None)
            self.last_bearing[s.sensor_id] = bearing
            self._pending(i, bearing)
            for u in held:  # every track the beam holds is looked at
                (x, P), track = (ep.predictions[u].x, ep.predictions[u].P), ep.tracks[u]
                fail = 1.0 - float(s.model.pd) * float(s.model.in_range(x, pv))
                before = self.looks.get(track.track_id, (0, 0, 1.0))[2]
                offset = wrap_angle(bearing - at[int(u)])
                width = cast(float, s.model.beam_width)
                coverage = float(sector_coverage(width, offset, x, P, pv))  # off centre too
                spread = float(position_spread(P))
                self.looks[track.track_id] = (
                    track.hits,
                    track.misses,
                    before * fail,
                    coverage,
                    spread,
                )
        ids = [t.track_id for t in ep.tracks]
        total = float(aggregate_costs(costs, ep.weights, self.settings.aggregate))
        return self._outcome(
            ep.epoch,
            ep.platforms,
            ep.plans,
            beams,
            dict(zip(ids, (float(c) for c in costs), strict=True)),
            search=self.search.search if self.search is not None and ep.plans else "hold",
            cost_names=("aggregate", "objective", *(f"track_{i}" for i in ids)),
            predicted_costs=(total, objective, *(float(c) for c in costs)),
            evaluations=ep.evaluations,
            wall_time_s=wall,
        )

    @staticmethod
    def _bearing(ep: _Epoch, t: int, pv: np.ndarray) -> float:
        """The bearing of track t's prediction from ``pv`` [rad]."""
        x = ep.predictions[t].x
        return math.atan2(x[2] - pv[2], x[0] - pv[0])

    def _sweep(
        self, epoch: int, planners: list[PlannerPlatform], start: float, tracks: TrackSet
    ) -> Decision:
        """No confirmed track: hold course, every beam one beam width on from where it was;
        with a surveillance region every beam searches instead (its most valuable pointing
        from where it will be, or a random one for random beams)."""
        beams = []
        steer = [i for i, s in enumerate(self.sensors) if s.steerable]
        options = None
        if self.undetected is not None and steer:
            ahead = np.stack([self._ahead(planners[self.sensors[i].platform].pv) for i in steer])
            found = self._search_options(tracks.tracks, steer, ahead)
            options = dict(zip(steer, found, strict=True))
        for i, s in enumerate(self.sensors):
            if s.model.beam_width is None:
                self._pending(i, None)
                continue
            last = self.last_bearing.get(s.sensor_id)
            heading = planners[s.platform].heading_and_speed[0]
            bearing = heading if last is None else float(wrap_angle(last + s.model.beam_width))
            track_id = -1
            if options is not None:
                o = options[i]
                if self.settings.assignment == "random":
                    j = int(self.rng.integers(len(o.bearings)))
                else:
                    j = int(np.argmax(o.values))
                bearing, track_id = float(o.bearings[j]), int(o.track_ids[j])
            self._pending(i, bearing)
            beams.append(BeamCommand(s.sensor_id, epoch, bearing, track_id))
            self.last_bearing[s.sensor_id] = bearing
            self.last_track.pop(s.sensor_id, None)
        wall = time.perf_counter() - start
        return self._outcome(epoch, planners, {}, beams, {}, search="sweep", wall_time_s=wall)

    def _outcome(
        self,
        epoch: int,
        planners: list[PlannerPlatform],
        plans: dict,
        beams: list[BeamCommand],
        track_costs: dict[int, float],
        **report: Any,
    ) -> Decision:
        """The decision: ``plans``' commands, the beams and the report (``report``: its
        fields beyond epoch, cost kind, criterion and horizon)."""
        return Decision(
            epoch,
            commands=tuple(self._commands(planners, epoch, plans)),
            beams=tuple(beams),
            report=PlanReportData(
                epoch,
                self.cost_kind,
                self.criterion.name,
                horizon=self.horizon if self.gospa is None else self.lookahead,
                **report,
            ),
            extra={
                "track_costs": track_costs,
                "assignment": {b.sensor_id: b.track_id for b in beams},
            },
        )
