"""Sensor positioning and selection with the modified Riccati equation (Ramdaras et al. 2010).

Both score a sensor at a (candidate) position by a criterion (:mod:`activetrack.planning.
criteria`: eq. 24-26) of the expected covariance one step ahead, eq. 23
(:func:`activetrack.bounds.mre.mre_predict`)::

    P^(j)_{k+1|k} = F [(1 - pd_j) P_{k|k-1} + pd_j P^(j)_{k|k}] F^T + Q

with H_j (eq. 13) at the predicted state and the sensor's planned position: positioning (sec.
4; over R legs, sec. 7) through :func:`activetrack.planning.horizons.search_horizon`, selection
(sec. 3, eq. 27) and the baselines of Ramdaras and Absil 2007a. Shapes: pv states ``(4,)``,
covariances ``(4, 4)``; candidates batched ``(..., 4)``.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from activetrack.arraytypes import ArrayLike
from activetrack.bounds.costs import trace_cost
from activetrack.bounds.mre import joseph_update, mre_mix, mre_predict, mre_update
from activetrack.checks import require_finite, require_spd, symmetrize
from activetrack.planning.criteria import POSITIONING, SELECTION, Criterion, get_criterion
from activetrack.planning.horizons import SearchSettings, check_horizon, search_horizon
from activetrack.planning.manoeuvre import PlannerPlatform, step_platform
from activetrack.planning.objective import CovarianceTerm, Objective

if TYPE_CHECKING:
    from activetrack.models.base import SensorModel

__all__ = [
    "DEFAULT_POSITIONING_SEARCH",
    "POSITIONING_SEARCHES",
    "MreStage",
    "PositioningResult",
    "SelectionResult",
    "TargetPrediction",
    "expected_update",
    "plan_positions",
    "position_platform",
    "select_by_criterion",
    "select_by_trace",
    "select_fixed",
    "select_random",
    "sensor_costs",
    "trace_costs",
]

POSITIONING_SEARCHES = ("sector", "quadrant", "grid")
# Ramdaras sec. 4-5: the nine-sector search to d_max = 5 levels.
DEFAULT_POSITIONING_SEARCH = SearchSettings(search="sector", grid_size=21, sector_levels=5)


def _check_inputs(P_pred: ArrayLike, x_pred: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    P = require_spd("P_pred", P_pred)
    x = require_finite("x_pred", x_pred)
    if P.shape != (4, 4) or x.shape != (4,):
        raise ValueError(f"P_pred must be (4, 4) and x_pred (4,) (pv), got {P.shape}, {x.shape}")
    return P, x


def _mre_criterion(name: str) -> Criterion:
    return get_criterion(name, POSITIONING, SELECTION)


@dataclass(frozen=True)
class TargetPrediction:
    """The epoch being planned for: x_{k+1|k} ``x`` ``(4,)`` and P_{k+1|k} ``P`` ``(4, 4)``
    (symmetric positive definite), and the target dynamics ``F``, ``Q`` ``(4, 4)`` over one
    interval, with which eq. 23 looks one interval further."""

    x: np.ndarray
    P: np.ndarray
    F: np.ndarray
    Q: np.ndarray

    def __post_init__(self) -> None:
        P, x = _check_inputs(self.P, self.x)
        F = require_finite("F", self.F)
        Q = require_finite("Q", self.Q)
        if F.shape != (4, 4) or Q.shape != (4, 4):
            raise ValueError(f"F and Q must be (4, 4) (pv), got {F.shape}, {Q.shape}")
        for name, value in (("x", x), ("P", P), ("F", F), ("Q", Q)):
            object.__setattr__(self, name, value)

    @classmethod
    def from_posterior(
        cls, x: ArrayLike, P: ArrayLike, F: np.ndarray, Q: np.ndarray
    ) -> TargetPrediction:
        """x_{k+1|k} = F x, P_{k+1|k} = F P F^T + Q from the posterior (x, P) at epoch k."""
        P_pred = F @ np.asarray(P, dtype=float) @ F.T + Q
        return cls(F @ np.asarray(x, dtype=float), 0.5 * (P_pred + P_pred.T), F, Q)

    @classmethod
    def from_posteriors(
        cls, xs: Sequence[ArrayLike], Ps: Sequence[ArrayLike], F: np.ndarray, Q: np.ndarray
    ) -> list[TargetPrediction]:
        """:meth:`from_posterior` of T posteriors ``(4,)``, ``(4, 4)`` under one dynamics, the
        covariances predicted and checked as one stack ``(T, 4, 4)`` (the same numbers)."""
        F, Q = require_finite("F", F), require_finite("Q", Q)
        if F.shape != (4, 4) or Q.shape != (4, 4):
            raise ValueError(f"F and Q must be (4, 4) (pv), got {F.shape}, {Q.shape}")
        if len(xs) != len(Ps):
            raise ValueError(f"xs and Ps must be as many, got {len(xs)} and {len(Ps)}")
        if not len(xs):
            return []
        P = np.stack([np.asarray(P, dtype=float) for P in Ps])
        if P.shape[1:] != (4, 4):
            raise ValueError(f"P_pred must be (4, 4) and x_pred (4,) (pv), got {P.shape[1:]}")
        P_pred = F @ P @ F.T + Q
        P_pred = require_spd("P_pred", 0.5 * (P_pred + np.swapaxes(P_pred, -1, -2)))
        out = []
        for x, P_t in zip(xs, P_pred, strict=True):
            x_pred = require_finite("x_pred", F @ np.asarray(x, dtype=float))
            if x_pred.shape != (4,):
                raise ValueError(f"P_pred must be (4, 4) and x_pred (4,) (pv), got {x_pred.shape}")
            p = cls.__new__(cls)
            for name, value in (("x", x_pred), ("P", P_t), ("F", F), ("Q", Q)):
                object.__setattr__(p, name, value)
            out.append(p)
        return out

    def with_covariance(self, P: np.ndarray) -> TargetPrediction:
        """The same epoch with another P_{k+1|k} (e.g. with the sensors picked so far)."""
        return replace(self, P=P)

    def after_look(
        self, sensor: SensorModel, sensor_pv: np.ndarray, detection: float
    ) -> TargetPrediction:
        """The same epoch after one possible look of ``sensor`` at ``sensor_pv`` ``(4,)`` with
        detection factor ``detection`` in [0, 1]: :func:`expected_update` of this prediction,
        which is valid already and whose update (Joseph form, a convex mix) is SPD by
        construction, so nothing is checked twice (a planner's inner loop)."""
        return self.after_sure_look(self.sure_look(sensor, sensor_pv), detection)

    def sure_look(self, sensor: SensorModel, sensor_pv: np.ndarray) -> tuple[np.ndarray, float]:
        """What :meth:`after_look` computes whatever the detection factor: P_{k|k} of a sure
        detection (:func:`~activetrack.bounds.mre.joseph_update`) and I_r (1.0 or 0.0), for
        :meth:`after_sure_look` with several factors."""
        P_upd = joseph_update(self.P, sensor.jacobian(self.x, sensor_pv), sensor.R)
        return P_upd, float(sensor.in_range(self.x, sensor_pv))

    def after_sure_look(self, look: tuple[np.ndarray, float], detection: float) -> TargetPrediction:
        """:meth:`after_look` from the :meth:`sure_look` of that sensor and pv (computed once
        for several detection factors)."""
        P_upd, in_range = look
        out = copy.copy(self)
        object.__setattr__(out, "P", mre_mix(self.P, P_upd, detection * in_range))
        return out


def expected_update(
    P_pred: ArrayLike,
    x_pred: ArrayLike,
    sensors: Sequence[SensorModel],
    sensor_pvs: ArrayLike,
    *,
    use_pd: bool = True,
    detection: ArrayLike | None = None,
) -> np.ndarray:
    """Expected covariance after sensors ``(S,)`` at pvs ``(S, 4)`` in turn: (1 - pd) P + pd
    P_{k|k} (eq. 23's bracket; ``use_pd=False``: eq. 22). ``detection`` ``(S,)`` replaces pd
    (e.g. an IRF times a field-of-view indicator); outside [r_min, r_max] there is no update.
    """
    P, x = _check_inputs(P_pred, x_pred)
    pvs = require_finite("sensor_pvs", _sensor_rows(sensors, sensor_pvs))
    factors = _detection_factors(sensors, detection, use_pd)
    for sensor, s, factor in zip(sensors, pvs, factors, strict=True):
        P = _look(P, x, sensor, s, factor)
    return P


def _look(
    P: np.ndarray, x: np.ndarray, sensor: SensorModel, sensor_pv: np.ndarray, factor: float
) -> np.ndarray:
    """One sensor's term of :func:`expected_update`; no update outside [r_min, r_max]."""
    pd = factor * float(sensor.in_range(x, sensor_pv))
    return mre_update(P, sensor.jacobian(x, sensor_pv), sensor.R, pd)


def _detection_factors(
    sensors: Sequence[SensorModel], detection: ArrayLike | None, use_pd: bool
) -> list[float]:
    if detection is None:
        return [float(s.pd) if use_pd else 1.0 for s in sensors]
    d = np.asarray(detection, dtype=float).reshape(-1)
    if d.shape != (len(sensors),) or not np.all((d >= 0.0) & (d <= 1.0)):
        raise ValueError(f"detection must hold {len(sensors)} factors in [0, 1], got {d}")
    return [float(v) for v in d]


def _sensor_rows(sensors: Sequence[SensorModel], sensor_pvs: ArrayLike) -> np.ndarray:
    pvs = np.asarray(sensor_pvs, dtype=float).reshape(-1, 4)
    if len(pvs) != len(sensors):
        raise ValueError(f"sensor_pvs must hold {len(sensors)} pv rows, got {len(pvs)}")
    return pvs


def sensor_costs(
    prediction: TargetPrediction,
    sensors: Sequence[SensorModel],
    sensor_pvs: ArrayLike,
    criterion: str,
) -> tuple[np.ndarray, np.ndarray]:
    """C^(j) (eq. 23 then the criterion, eq. 24-26) of each sensor at its pv: ``(costs (S,),
    expected covariances (S, 4, 4))``."""
    crit = _mre_criterion(criterion)
    pvs = _sensor_rows(sensors, sensor_pvs)
    p = prediction
    P_hat = np.stack(
        [mre_predict(p.P, p.F, p.Q, s, p.x, pv) for s, pv in zip(sensors, pvs, strict=True)]
    )
    return crit.of_covariance(P_hat, p.x), P_hat


def trace_costs(
    prediction: TargetPrediction, sensors: Sequence[SensorModel], sensor_pvs: ArrayLike
) -> np.ndarray:
    """tr(P^(j)_{k|k}) of the Kalman update (eq. 22, pd ignored) for each sensor ``(S,)``."""
    pvs = _sensor_rows(sensors, sensor_pvs)
    upd = np.stack(
        [
            expected_update(prediction.P, prediction.x, [s], pv, use_pd=False)
            for s, pv in zip(sensors, pvs, strict=True)
        ]
    )
    return trace_cost(upd)


@dataclass(frozen=True)
class SelectionResult:
    """Selected sensor indices (pick order), the candidates' costs ``(S,)`` under
    ``cost_name`` (the first pick's scores) and the evaluations spent."""

    selected: tuple[int, ...]
    costs: np.ndarray
    cost_name: str
    evaluations: int


def _check_count(count: int, n_sensors: int) -> int:
    if isinstance(count, bool) or int(count) != count or not 1 <= count <= n_sensors:
        raise ValueError(f"count must be an integer in [1, {n_sensors}], got {count!r}")
    return int(count)


# costs_of(prediction, sensors (S,), pvs (S, 4)) -> the sensors' costs (S,)
_CostsOf = Callable[[TargetPrediction, list["SensorModel"], np.ndarray], np.ndarray]


def _greedy(
    prediction: TargetPrediction,
    sensors: Sequence[SensorModel],
    sensor_pvs: ArrayLike,
    count: int,
    use_pd: bool,
    costs_of: _CostsOf,
    cost_name: str,
) -> SelectionResult:
    """argmin of ``costs_of``, then (count > 1) each further pick the argmin over the rest with
    the picks folded into the prediction (pd-weighted with ``use_pd``)."""
    count = _check_count(count, len(sensors))
    pvs = _sensor_rows(sensors, sensor_pvs)
    costs = np.asarray(costs_of(prediction, list(sensors), pvs), dtype=float)
    picks = [int(np.argmin(costs))]
    remaining = [i for i in range(len(sensors)) if i != picks[0]]
    evaluations = len(sensors)
    while len(picks) < count:
        P_sel = expected_update(
            prediction.P, prediction.x, [sensors[i] for i in picks], pvs[picks], use_pd=use_pd
        )
        rest = [sensors[i] for i in remaining]
        c = costs_of(prediction.with_covariance(P_sel), rest, pvs[remaining])
        evaluations += len(remaining)
        picks.append(remaining.pop(int(np.argmin(c))))
    return SelectionResult(tuple(picks), costs, cost_name, evaluations)


def select_by_criterion(
    prediction: TargetPrediction,
    sensors: Sequence[SensorModel],
    sensor_pvs: ArrayLike,
    *,
    criterion: str = "det_pos",
    count: int = 1,
) -> SelectionResult:
    """Ramdaras eq. 27: the sensor(s) minimising ``criterion`` of eq. 23, ``(S, 4)`` pvs.

    Ties go to the lower index; ``count`` > 1 picks greedily, folding each pick in with its pd.
    """
    return _greedy(
        prediction,
        sensors,
        sensor_pvs,
        count,
        True,
        lambda p, rest, pvs: sensor_costs(p, rest, pvs, criterion)[0],
        criterion,
    )


def select_by_trace(
    prediction: TargetPrediction,
    sensors: Sequence[SensorModel],
    sensor_pvs: ArrayLike,
    *,
    count: int = 1,
) -> SelectionResult:
    """The trace baseline: argmin tr(P_{k|k}) of the Kalman update (eq. 22, pd ignored)."""
    return _greedy(prediction, sensors, sensor_pvs, count, False, trace_costs, "trace")


def select_random(
    prediction: TargetPrediction,
    sensors: Sequence[SensorModel],
    sensor_pvs: ArrayLike,
    rng: np.random.Generator,
    *,
    criterion: str = "det_pos",
    count: int = 1,
) -> SelectionResult:
    """The random baseline: ``count`` distinct sensors drawn uniformly by ``rng`` (one
    ``rng.choice`` per call); the MRE costs under ``criterion`` are reported for the record."""
    count = _check_count(count, len(sensors))
    costs, _ = sensor_costs(prediction, sensors, sensor_pvs, criterion)
    if not isinstance(rng, np.random.Generator):
        raise ValueError("rng must be a numpy Generator for random selection")
    picks = tuple(int(i) for i in rng.choice(len(sensors), size=count, replace=False))
    return SelectionResult(picks, np.asarray(costs, dtype=float), criterion, len(sensors))


def select_fixed(
    prediction: TargetPrediction,
    sensors: Sequence[SensorModel],
    sensor_pvs: ArrayLike,
    index: int,
    *,
    criterion: str = "det_pos",
) -> SelectionResult:
    """The fixed baseline: always sensor ``index``; the MRE costs are reported for the record."""
    S = len(sensors)
    if isinstance(index, bool) or not isinstance(index, int | np.integer) or not 0 <= index < S:
        raise ValueError(f"index must be a sensor index in [0, {S}), got {index!r}")
    costs, _ = sensor_costs(prediction, sensors, sensor_pvs, criterion)
    return SelectionResult((int(index),), np.asarray(costs, dtype=float), criterion, S)


@dataclass(frozen=True)
class PositioningResult:
    """The chosen manoeuvre (dpsi, v') ``(2,)``, the platform pv at k+1 ``(4,)``, the new
    heading, the criterion there and the cost evaluations of the search; ``plan`` ``(R, 2)``:
    the manoeuvres over the horizon (row 0 is ``manoeuvre``, the one flown)."""

    manoeuvre: np.ndarray
    next_pv: np.ndarray
    heading: float
    cost: float
    evaluations: int
    plan: np.ndarray | None = None


def position_platform(
    platform: PlannerPlatform,
    prediction: TargetPrediction,
    dt: float,
    *,
    criterion: str = "det_pos",
    search: SearchSettings = DEFAULT_POSITIONING_SEARCH,
    horizon: int = 1,
) -> PositioningResult:
    """Ramdaras sec. 4: the controllable ``platform``'s next position minimising the MRE
    criterion of eq. 23 with all its sensors there in turn, by ``search`` (``"sector"``:
    ``sector_levels`` = d_max; ``"quadrant"``, ``"grid"`` for comparison); ``horizon`` >= 2:
    :func:`plan_positions`, the first of R manoeuvres."""
    return plan_positions(
        platform, prediction, dt, criterion=criterion, search=search, horizon=horizon
    )


@dataclass(frozen=True)
class MreStage:
    """One platform's sensors over R legs of eq. 23 for one target (a :class:`HorizonStage`):
    P_{k+1+r|k+r} ``(..., 1, 4, 4)``, updated by the sensors in turn at the CV prediction
    x_{k+1+r|k} = F^r x_{k+1|k} (``x`` ``(R, 4)``), then predicted one interval."""

    sensors: tuple[SensorModel, ...]
    x: np.ndarray
    F: np.ndarray
    Q: np.ndarray

    def prepare(self, P: np.ndarray, level: int) -> np.ndarray:
        # F P F^T + Q of the previous leg, round-off asymmetry removed.
        return P if level == 0 else symmetrize(P)

    def advance(self, P: np.ndarray, level: int, pv: np.ndarray) -> np.ndarray:
        P, x = P[..., 0, :, :], self.x[level]
        for sensor in self.sensors:
            pd = float(sensor.pd) * sensor.in_range(x, pv)
            P = mre_update(P, sensor.jacobian(x, pv), sensor.R, pd)
        return (self.F @ P @ self.F.T + self.Q)[..., None, :, :]


def plan_positions(
    platform: PlannerPlatform,
    prediction: TargetPrediction,
    dt: float,
    *,
    criterion: str = "det_pos",
    search: SearchSettings = DEFAULT_POSITIONING_SEARCH,
    horizon: int = 2,
) -> PositioningResult:
    """Multi-step MRE positioning (Ramdaras sec. 7, future work): ``platform``'s R-leg
    manoeuvres minimising ``criterion`` of P_{k+R+1|k+R} (:class:`MreStage`); the first is
    flown. The cost is after leg R, not summed over the legs: the covariance at k+R already
    holds every update along the path, so a sum would count the early gains again and pull
    towards the greedy one-step choice. R = 1 is :func:`position_platform`.
    """
    R = check_horizon(horizon)
    if platform.limits is None:
        raise ValueError(f"platform {platform.platform_id!r} must be controllable (have limits)")
    if search.search not in POSITIONING_SEARCHES:
        raise ValueError(f"search must be one of {POSITIONING_SEARCHES}, got {search.search!r}")
    crit = _mre_criterion(criterion)
    p = prediction
    x = np.stack([np.linalg.matrix_power(p.F, r) @ p.x for r in range(R)])
    for xr in x:
        crit.of_covariance(p.P, xr)  # fails early where the criterion is undefined
    stage = MreStage(tuple(platform.sensors), x, p.F, p.Q)
    objective = Objective((CovarianceTerm(crit, x[:, None]),))
    best = search_horizon(stage, objective, p.P[None], platform, dt, search, R)
    heading = platform.heading_and_speed[0]
    nxt, psi = step_platform(platform.pv, heading, best.plan[0], dt)
    return PositioningResult(
        best.plan[0], nxt, float(psi), best.objective, best.evaluations, plan=best.plan
    )
