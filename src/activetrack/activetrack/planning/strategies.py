"""Planner strategies of the papers, run in order by :class:`activetrack.planning.decision.
Planner` and built by :func:`activetrack.closed_loop.components.build_planner`. Only
:class:`PcrlbPlanning` and :class:`RandomSelection` draw, from the planner's generator, in that
order.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from activetrack.bounds.costs import position_determinant, trace_cost
from activetrack.bounds.pcrlb import covariance_bound
from activetrack.data import Command, PlanReportData, TrackEstimate
from activetrack.models.base import SensorModel
from activetrack.planning.cautious import CautiousController
from activetrack.planning.criteria import POSITIONING, SELECTION, get_criterion
from activetrack.planning.decision import DecisionContext, DecisionPart, SensorChoice
from activetrack.planning.horizons import SearchSettings
from activetrack.planning.manoeuvre import PlannerPlatform, PlatformLimits
from activetrack.planning.planner import PlanSettings, TargetBelief, advance_belief, plan
from activetrack.planning.selection import (
    POSITIONING_SEARCHES,
    SelectionResult,
    TargetPrediction,
    expected_update,
    position_platform,
    select_by_criterion,
    select_by_trace,
    select_fixed,
    select_random,
)

__all__ = [
    "MRE_REPORT_COSTS",
    "CautiousLocalisation",
    "FixedSelection",
    "HoldCourse",
    "LinearDynamics",
    "MreOutlook",
    "MrePositioning",
    "MrePrediction",
    "MreSelection",
    "PcrlbPlanning",
    "PlatformSpec",
    "RandomSelection",
    "SensorEntry",
    "TraceSelection",
]

# Cost names of the plan report in MRE mode (predicted for the epoch decided for, k+1).
MRE_REPORT_COSTS = ("objective", "det_pos", "trace", "det_pos_updated", "trace_updated")


@dataclass(frozen=True)
class LinearDynamics:
    """The target's linear pv dynamics over one interval dt: F, Q ``(4, 4)`` (Hernandez
    eq. 2, Ramdaras eq. 3-4), which PCRLB planning and the MRE need."""

    F: np.ndarray
    Q: np.ndarray
    dt: float


@dataclass(frozen=True)
class PlatformSpec:
    """A platform as the planner knows it between decisions: its id, its sensors' models and
    its per-epoch limits (None: not steered, it holds course)."""

    platform_id: str
    sensors: tuple[SensorModel, ...]
    limits: PlatformLimits | None = None


@dataclass(frozen=True)
class SensorEntry:
    """One sensor of the scene: its id, the platform carrying it and its model."""

    sensor_id: str
    platform_id: str
    model: SensorModel


def _require_pv(track: TrackEstimate) -> None:
    if track.state.shape != (4,):
        raise ValueError(
            f"track: renewal planning needs a pv track (x, xdot, y, ydot), got a state of "
            f"{track.state.shape[0]} entries"
        )


class HoldCourse:
    """Hold course and speed: the commands of a planner that is off."""

    def __init__(self, platform_ids: Sequence[str]):
        self.platform_ids = tuple(platform_ids)

    def decide(self, context: DecisionContext) -> DecisionPart:
        return DecisionPart(tuple(Command(p, context.epoch, 0.0, 0.0) for p in self.platform_ids))


class PcrlbPlanning:
    """PCRLB manoeuvre planning (Hernandez sec. 3-4) of every controllable platform by
    :func:`activetrack.planning.planner.plan`: renewal (each decision from the track's
    posterior, footnote 2) or open loop (from the prior and the known dynamics, sec. 3.2)."""

    def __init__(
        self,
        settings: PlanSettings,
        platforms: Sequence[PlatformSpec],
        dynamics: LinearDynamics,
        rng: np.random.Generator,
        *,
        mc_samples: int,
        open_loop_prior: tuple[np.ndarray, np.ndarray] | None = None,
    ):
        self.settings = settings
        self.platforms = tuple(platforms)
        self.prior = open_loop_prior  # None: renewal
        self.mc_samples = mc_samples
        self.dynamics = dynamics
        self.rng = rng
        self._open_loop_belief: TargetBelief | None = None

    def _belief(
        self, epoch: int, track: TrackEstimate, platforms: list[PlannerPlatform]
    ) -> TargetBelief:
        d = self.dynamics
        if self.prior is not None:
            if self._open_loop_belief is None:
                mean, cov = self.prior
                self._open_loop_belief = TargetBelief.from_gaussian(
                    mean, cov, self.mc_samples, self.rng
                )
            elif epoch > 0:
                self._open_loop_belief = advance_belief(
                    self._open_loop_belief, platforms, d.F, d.Q, self.rng
                )
            return self._open_loop_belief
        _require_pv(track)
        if track.samples is not None:
            return TargetBelief(covariance_bound(track.state_cov), track.samples)
        return TargetBelief.from_gaussian(track.state, track.state_cov, self.mc_samples, self.rng)

    def decide(self, context: DecisionContext) -> DecisionPart:
        platforms = [
            PlannerPlatform(
                p.platform_id,
                np.asarray(context.platforms[p.platform_id].pv, float),
                p.sensors,
                p.limits,
            )
            for p in self.platforms
        ]
        belief = self._belief(context.epoch, context.track, platforms)
        d = self.dynamics
        result = plan(platforms, belief, self.settings, F=d.F, Q=d.Q, dt=d.dt, rng=self.rng)
        epoch, r = context.epoch, result.report
        report = PlanReportData(
            epoch=epoch,
            cost_kind="pcrlb",
            criterion=r.criterion,
            search=r.search,
            horizon=r.horizon,
            cost_names=r.cost_names,
            predicted_costs=tuple(float(c) for c in r.predicted_costs),
        )
        return DecisionPart(
            commands=tuple(
                Command(m.platform_id, epoch, m.heading_change, m.speed_change, m.heading, m.speed)
                for m in result.manoeuvres
            ),
            planned_pv={m.platform_id: m.next_pv for m in result.manoeuvres},
            report=report,
            evaluations=r.evaluations,
        )


class CautiousLocalisation:
    """Stop-and-measure localisation of a target by one robot (Vander Hook et al., Alg. 1)
    through :class:`activetrack.planning.cautious.CautiousController`."""

    def __init__(self, controller: CautiousController):
        self.controller = controller

    def decide(self, context: DecisionContext) -> DecisionPart:
        c = self.controller
        command = c.decide(context.epoch, context.track, context.platforms[c.robot_id])
        report = PlanReportData(
            epoch=context.epoch,
            cost_kind="cautious",
            criterion="eigenvalues",
            search="cautious",
            horizon=1,
            cost_names=("measurements", "done"),
            predicted_costs=(float(c.measurements), float(c.done)),
        )
        return DecisionPart(commands=(command,), report=report)


class MrePrediction:
    """x_{k+1|k} = F x, P_{k+1|k} = F P F^T + Q for the MRE strategies after it.

    Renewal: (x, P) is the track's posterior (Ramdaras Fig. 5). Open loop: the planner's own
    recursion from the prior, P_{k+1|k+1} = (1 - pd) P_{k+1|k} + pd P^(j)_{k+1|k+1} for the
    chosen sensors, which :class:`MreOutlook` feeds back through :meth:`commit`."""

    def __init__(
        self,
        dynamics: LinearDynamics,
        open_loop_prior: tuple[np.ndarray, np.ndarray] | None = None,
    ):
        self.prior = open_loop_prior  # None: renewal
        self.dynamics = dynamics
        self._posterior: tuple[np.ndarray, np.ndarray] | None = None

    def decide(self, context: DecisionContext) -> DecisionPart:
        if self.prior is not None:
            if self._posterior is None:
                mean, cov = self.prior
                self._posterior = (np.array(mean, dtype=float), np.array(cov, dtype=float))
            x, P = self._posterior
        else:
            _require_pv(context.track)
            x, P = context.track.state, context.track.state_cov
        d = self.dynamics
        return DecisionPart(prediction=TargetPrediction.from_posterior(x, P, d.F, d.Q))

    def commit(self, x: np.ndarray, P_updated: np.ndarray) -> None:
        """Open loop: the expected posterior at k+1 the next decision predicts from."""
        if self.prior is not None:
            self._posterior = (x, P_updated)


class MrePositioning:
    """Ramdaras sec. 4: each controllable platform on its own to the position minimising the
    criterion of eq. 23 with all its sensors there (:func:`position_platform`); with
    ``planner.horizon`` R >= 2 the first of R manoeuvres minimising it after R legs (sec. 7's
    multi-step positioning, :func:`activetrack.planning.selection.plan_positions`)."""

    def __init__(
        self,
        criterion: str,
        search: SearchSettings,
        platforms: Sequence[PlatformSpec],
        dt: float,
        horizon: int = 1,
    ):
        self.criterion = get_criterion(criterion, POSITIONING, what="planner.criterion").name
        self.search = search
        if search.search not in POSITIONING_SEARCHES:
            raise ValueError(
                f"planner.search must be one of {POSITIONING_SEARCHES} with cost 'mre', "
                f"got {search.search!r}"
            )
        self.dt = dt
        self.horizon = horizon
        self.platforms = tuple(
            (p.platform_id, p.limits, p.sensors) for p in platforms if p.limits is not None
        )

    def decide(self, context: DecisionContext) -> DecisionPart:
        commands, planned, costs, evaluations = [], {}, {}, 0
        for pid, limits, models in self.platforms:
            snap = context.platforms[pid]
            platform = PlannerPlatform(
                pid, snap.pv, models, limits, heading=snap.heading, speed=snap.speed
            )
            pos = position_platform(
                platform,
                context.prediction,
                self.dt,
                criterion=self.criterion,
                search=self.search,
                horizon=self.horizon,
            )
            dpsi, v = float(pos.manoeuvre[0]), float(pos.manoeuvre[1])
            commands.append(Command(pid, context.epoch, dpsi, v - snap.speed, pos.heading, v))
            planned[pid] = pos.next_pv
            costs[pid] = pos.cost
            evaluations += pos.evaluations
        return DecisionPart(
            tuple(commands), planned, evaluations=evaluations, extra={"positioning_costs": costs}
        )


class _Selection:
    """Common part of the selection strategies (Ramdaras sec. 3): every sensor at its
    platform's pv at k+1 is a candidate; ``count`` of them measure at k+1; ``criterion`` the
    MRE cost they are scored (or, for the baselines, reported) by."""

    name = ""

    def __init__(self, sensors: Sequence[SensorEntry], count: int, criterion: str = "det_pos"):
        self.sensors = tuple(sensors)
        self.models = [s.model for s in self.sensors]
        if not 1 <= count <= len(self.sensors):
            raise ValueError(
                f"planner.selection.count must be <= {len(self.sensors)} sensors, got {count}"
            )
        self.count = count
        self.criterion = get_criterion(
            criterion, SELECTION, what="planner.selection.criterion"
        ).name

    def select(self, prediction: TargetPrediction, pvs: np.ndarray) -> SelectionResult:
        raise NotImplementedError

    def decide(self, context: DecisionContext) -> DecisionPart:
        pvs = np.stack([context.next_pv(s.platform_id) for s in self.sensors])
        result = self.select(context.prediction, pvs)
        chosen = tuple(sorted(result.selected))
        choice = SensorChoice(
            indices=chosen,
            sensor_ids=tuple(self.sensors[i].sensor_id for i in chosen),
            candidate_ids=tuple(s.sensor_id for s in self.sensors),
            costs=tuple(float(c) for c in result.costs),
            label=f"{self.name}/{result.cost_name}",
        )
        return DecisionPart(selection=choice, evaluations=result.evaluations)


class MreSelection(_Selection):
    """Ramdaras eq. 27: argmin of the criterion of eq. 23 (greedy for count > 1)."""

    name = "mre"

    def __init__(self, sensors: Sequence[SensorEntry], criterion: str, count: int = 1):
        super().__init__(sensors, count, criterion)

    def select(self, prediction: TargetPrediction, pvs: np.ndarray) -> SelectionResult:
        return select_by_criterion(
            prediction, self.models, pvs, criterion=self.criterion, count=self.count
        )


class TraceSelection(_Selection):
    """Baseline: argmin of tr(P_{k|k}) of the Kalman update (eq. 22, pd ignored)."""

    name = "trace"

    def select(self, prediction: TargetPrediction, pvs: np.ndarray) -> SelectionResult:
        return select_by_trace(prediction, self.models, pvs, count=self.count)


class RandomSelection(_Selection):
    """Baseline: ``count`` sensors drawn uniformly from the planner's generator."""

    name = "random"

    def __init__(
        self,
        sensors: Sequence[SensorEntry],
        criterion: str,
        count: int,
        rng: np.random.Generator,
    ):
        super().__init__(sensors, count, criterion)
        self.rng = rng

    def select(self, prediction: TargetPrediction, pvs: np.ndarray) -> SelectionResult:
        return select_random(
            prediction, self.models, pvs, self.rng, criterion=self.criterion, count=self.count
        )


class FixedSelection(_Selection):
    """Baseline: always the sensor ``sensor_id``."""

    name = "fixed"

    def __init__(self, sensors: Sequence[SensorEntry], criterion: str, sensor_id: str | None):
        super().__init__(sensors, 1, criterion)
        ids = [s.sensor_id for s in self.sensors]
        if sensor_id not in ids:
            raise ValueError(f"planner.selection.fixed_sensor must be one of {ids}")
        self.index = ids.index(sensor_id)

    def select(self, prediction: TargetPrediction, pvs: np.ndarray) -> SelectionResult:
        return select_fixed(prediction, self.models, pvs, self.index, criterion=self.criterion)


class MreOutlook:
    """The MRE plan report: eq. 23 with the chosen sensors (all of them without a selection)
    at their planned positions, the criterion of the result as the objective, and the open-loop
    recursion's next posterior (:meth:`MrePrediction.commit`).

    Report costs ``MRE_REPORT_COSTS``; ``extra``: ``mre_cov`` (P_{k+2|k+1}),
    ``mre_updated_cov`` (the expected P_{k+1|k+1}) and ``planned_pv`` (every platform)."""

    def __init__(
        self,
        platform_ids: Sequence[str],
        sensors: Sequence[SensorEntry],
        predictor: MrePrediction,
        criterion: str,
        search: str,
    ):
        self.platform_ids = tuple(platform_ids)
        self.sensors = tuple(sensors)
        self.predictor = predictor
        self.criterion = get_criterion(criterion, POSITIONING, SELECTION)
        self.search = search

    def decide(self, context: DecisionContext) -> DecisionPart:
        p = context.prediction
        selection = context.so_far.selection
        chosen = list(selection.indices if selection else range(len(self.sensors)))
        pvs = np.stack([context.next_pv(s.platform_id) for s in self.sensors])
        P_upd = expected_update(p.P, p.x, [self.sensors[i].model for i in chosen], pvs[chosen])
        P_hat = p.F @ P_upd @ p.F.T + p.Q
        P_hat = 0.5 * (P_hat + P_hat.T)
        self.predictor.commit(p.x, P_upd)
        report = PlanReportData(
            epoch=context.epoch,
            cost_kind="mre",
            criterion=self.criterion.name,
            search=self.search,
            horizon=1,
            cost_names=MRE_REPORT_COSTS,
            predicted_costs=(
                float(self.criterion.of_covariance(P_hat, p.x)),
                float(position_determinant(P_hat)),
                float(trace_cost(P_hat)),
                float(position_determinant(P_upd)),
                float(trace_cost(P_upd)),
            ),
        )
        planned = {pid: context.next_pv(pid) for pid in self.platform_ids}
        extra = {"mre_cov": P_hat, "mre_updated_cov": P_upd, "planned_pv": planned}
        return DecisionPart(report=report, extra=extra)
