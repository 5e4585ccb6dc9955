"""Sensor positioning and selection with the modified Riccati equation (Ramdaras et al. 2010).

Both steps score a sensor at a (candidate) position by the expected covariance one step ahead,
Ramdaras eq. 23 (:func:`activetrack.bounds.mre.mre_predict`)::

    P^(j)_{k+1|k} = F [(1 - pd_j) P_{k|k-1} + pd_j P^(j)_{k|k}] F^T + Q

with P_{k|k-1} the predicted covariance of the epoch being planned and H_j (eq. 13) at the
predicted target state x_{k|k-1} and the sensor's planned position, and by a criterion on it:
the position determinant (eq. 24) or H^c P H^c^T for heading, range, Doppler or bearing
(eq. 25-26, geometry relative to the origin as printed in eq. 26).

- Positioning (sec. 4, Fig. 4-6): each controllable platform independently searches its
  reachable envelope (the unit square of :mod:`activetrack.planning.manoeuvre`) with the
  nine-sector search (``d_max`` = levels); the cost of a candidate position is the criterion of
  eq. 23 with all of the platform's sensors there.
- Selection (sec. 3, eq. 27): j = argmin_j C^(j) over every sensor at its planned position.
  Baselines (Ramdaras and Absil 2007a): random (the caller's generator), fixed, and trace of
  the Kalman-updated covariance P^(j)_{k|k} (eq. 22, pd ignored: the classic covariance-control
  rule that the MRE improves on when pd < 1). ``count`` > 1 selects greedily: each pick is
  folded into P_{k|k-1} by the pd-weighted update before scoring the rest.

Shapes: pv states ``(4,)``, covariances ``(4, 4)``; candidates are batched ``(..., 4)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from activetrack.bounds.costs import (
    CRITERIA,
    criterion_variance,
    position_determinant,
    rmse_bound,
    trace_cost,
)
from activetrack.bounds.mre import mre_predict, mre_update
from activetrack.checks import require_finite, require_spd
from activetrack.planning.horizons import SearchSettings
from activetrack.planning.manoeuvre import PlatformLimits, step_platform, unit_to_manoeuvre

__all__ = [
    "MRE_CRITERIA",
    "STRATEGIES",
    "PositioningResult",
    "SelectionResult",
    "expected_update",
    "mre_criterion",
    "position_platform",
    "select_sensors",
    "sensor_costs",
]

MRE_CRITERIA = ("det_pos", "trace", "b_k", *CRITERIA)
STRATEGIES = ("mre", "random", "fixed", "trace")
POSITIONING_SEARCHES = ("sector", "quadrant", "grid")


def mre_criterion(name: str, P, x_pred) -> np.ndarray:
    """Cost ``name`` of covariances ``P`` ``(..., 4, 4) -> (...)``.

    det_pos: eq. 24; heading / range / doppler / bearing: eq. 25 with H^c of eq. 26 at the
    predicted target pv ``x_pred`` ``(4,)``; trace and b_k (Hernandez eq. 10) for comparison.
    """
    if name == "det_pos":
        return position_determinant(P)
    if name == "trace":
        return trace_cost(P)
    if name == "b_k":
        return rmse_bound(P)
    if name in CRITERIA:
        return criterion_variance(name, P, x_pred)
    raise ValueError(f"criterion must be one of {MRE_CRITERIA}, got {name!r}")


def _check_inputs(P_pred, x_pred):
    P_pred = require_spd("P_pred", P_pred)
    x_pred = require_finite("x_pred", x_pred)
    if P_pred.shape != (4, 4) or x_pred.shape != (4,):
        raise ValueError(
            f"P_pred must be (4, 4) and x_pred (4,) (pv), got {P_pred.shape}, {x_pred.shape}"
        )
    return P_pred, x_pred


def expected_update(P_pred, x_pred, sensors: Sequence, sensor_pvs, *, use_pd: bool = True):
    """Expected updated covariance after sensors ``(S,)`` at pvs ``(S, 4)``, applied in turn:
    (1 - pd) P + pd P_{k|k} (the bracket of eq. 23); ``use_pd=False``: the Kalman update, eq. 22.

    Inside a sensor's [r_min, r_max] gap the detection probability is 0 (no update).
    """
    P, x = _check_inputs(P_pred, x_pred)
    pvs = require_finite("sensor_pvs", np.asarray(sensor_pvs, dtype=float).reshape(-1, 4))
    if len(pvs) != len(sensors):
        raise ValueError(f"sensor_pvs must hold {len(sensors)} pv rows, got {len(pvs)}")
    for sensor, s in zip(sensors, pvs, strict=True):
        pd = float(sensor.pd) if use_pd else 1.0
        pd *= float(sensor.in_range(x, s))
        P = mre_update(P, sensor.jacobian(x, s), sensor.R, pd)
    return P


def sensor_costs(P_pred, F, Q, x_pred, sensors: Sequence, sensor_pvs, criterion: str):
    """C^(j) for each sensor at its pv: ``(costs (S,), expected covariances (S, 4, 4))``.

    MRE eq. 23 then the criterion (eq. 24-26). Sensors differ in dim_z, so this loops over the
    S sensors (a handful), each call batched over nothing more.
    """
    P_pred, x_pred = _check_inputs(P_pred, x_pred)
    pvs = np.asarray(sensor_pvs, dtype=float).reshape(-1, 4)
    if len(pvs) != len(sensors):
        raise ValueError(f"sensor_pvs must hold {len(sensors)} pv rows, got {len(pvs)}")
    P_hat = np.stack(
        [mre_predict(P_pred, F, Q, s, x_pred, pv) for s, pv in zip(sensors, pvs, strict=True)]
    )
    return mre_criterion(criterion, P_hat, x_pred), P_hat


@dataclass(frozen=True)
class SelectionResult:
    """Selected sensor indices (pick order), the candidates' costs ``(S,)`` under
    ``cost_name`` (the first pick's scores) and the evaluations spent."""

    selected: tuple[int, ...]
    costs: np.ndarray
    cost_name: str
    evaluations: int


def select_sensors(
    strategy: str,
    P_pred,
    F,
    Q,
    x_pred,
    sensors: Sequence,
    sensor_pvs,
    *,
    criterion: str = "det_pos",
    count: int = 1,
    fixed: int | None = None,
    rng: np.random.Generator | None = None,
) -> SelectionResult:
    """Ramdaras eq. 27 (``"mre"``) or a baseline (``"random"``, ``"fixed"``, ``"trace"``).

    ``P_pred`` ``(4, 4)`` and ``x_pred`` ``(4,)``: predicted covariance and state for the epoch
    being selected for; sensors at ``sensor_pvs`` ``(S, 4)``. ``fixed`` is the sensor index for
    the fixed strategy; ``rng`` draws the random one. Random and fixed still report the MRE
    costs (for the record); ties go to the lower index.
    """
    if strategy not in STRATEGIES:
        raise ValueError(f"strategy must be one of {STRATEGIES}, got {strategy!r}")
    S = len(sensors)
    if isinstance(count, bool) or int(count) != count or not 1 <= count <= S:
        raise ValueError(f"count must be an integer in [1, {S}], got {count!r}")
    pvs = np.asarray(sensor_pvs, dtype=float).reshape(-1, 4)
    P, x = _check_inputs(P_pred, x_pred)
    if strategy == "trace":
        upd = np.stack(
            [
                expected_update(P, x, [s], pv, use_pd=False)
                for s, pv in zip(sensors, pvs, strict=True)
            ]
        )
        costs = trace_cost(upd)
        cost_name = "trace"
    else:
        costs, _ = sensor_costs(P, F, Q, x, sensors, pvs, criterion)
        cost_name = criterion
    evaluations = S
    if strategy == "random":
        if not isinstance(rng, np.random.Generator):
            raise ValueError("rng must be a numpy Generator for random selection")
        picks = tuple(int(i) for i in rng.choice(S, size=int(count), replace=False))
    elif strategy == "fixed":
        if fixed is None or not 0 <= int(fixed) < S:
            raise ValueError(f"fixed must be a sensor index in [0, {S}), got {fixed!r}")
        picks = (int(fixed),)
    else:
        picks = [int(np.argmin(costs))]
        remaining = [i for i in range(S) if i != picks[0]]
        while len(picks) < count:
            # Fold the picks into the prediction (pd-weighted for MRE) and score the rest.
            P_sel = expected_update(
                P, x, [sensors[i] for i in picks], pvs[picks], use_pd=strategy == "mre"
            )
            if strategy == "mre":
                c, _ = sensor_costs(
                    P_sel, F, Q, x, [sensors[i] for i in remaining], pvs[remaining], criterion
                )
            else:
                c = trace_cost(
                    np.stack(
                        [
                            expected_update(P_sel, x, [sensors[i]], pvs[i], use_pd=False)
                            for i in remaining
                        ]
                    )
                )
            evaluations += len(remaining)
            picks.append(remaining.pop(int(np.argmin(c))))
        picks = tuple(picks)
    return SelectionResult(picks, np.asarray(costs, dtype=float), cost_name, evaluations)


@dataclass(frozen=True)
class PositioningResult:
    """The chosen manoeuvre (dpsi, v') ``(2,)``, the platform pv at k+1 ``(4,)``, the new
    heading, the criterion there and the cost evaluations of the search."""

    manoeuvre: np.ndarray
    next_pv: np.ndarray
    heading: float
    cost: float
    evaluations: int


def position_platform(
    pv,
    heading: float,
    speed: float,
    limits: PlatformLimits,
    sensors: Sequence,
    P_pred,
    F,
    Q,
    x_pred,
    dt: float,
    *,
    criterion: str = "det_pos",
    search: str = "sector",
    levels: int = 5,
    grid_size: int = 21,
    divisions: int = 6,
    patience: int | None = None,
) -> PositioningResult:
    """Ramdaras sec. 4: the platform's next position minimising the MRE criterion.

    The reachable envelope (heading change +-dpsi_max, speed in [v_lo, v_hi]) is searched by
    ``search`` (``"sector"``: nine sectors, ``levels`` = d_max; ``"quadrant"``, ``"grid"`` for
    comparison). A candidate's cost is eq. 23 with all ``sensors`` of the platform at the
    candidate pv (sequential updates), then ``criterion``. Candidates of a stage are scored in
    one batched :func:`activetrack.bounds.mre.mre_update` call per sensor.
    """
    P_pred, x_pred = _check_inputs(P_pred, x_pred)
    F = require_finite("F", F)
    Q = require_finite("Q", Q)
    pv = require_finite("pv", pv)
    if search not in POSITIONING_SEARCHES:
        raise ValueError(f"search must be one of {POSITIONING_SEARCHES}, got {search!r}")
    mre_criterion(criterion, P_pred, x_pred)  # validates the name early
    sensors = tuple(sensors)

    def candidates(u):
        m = unit_to_manoeuvre(u, speed, limits)
        nxt, psi = step_platform(pv, heading, m, dt)
        return m, nxt, psi

    def cost_fn(rows, u):
        _, nxt, _ = candidates(u)  # (b, C, 4)
        # Eq. 23 with the platform's sensors applied in turn (mre_predict without re-checking
        # the inputs at every stage of the search).
        P = P_pred
        for sensor in sensors:
            pd = float(sensor.pd) * sensor.in_range(x_pred, nxt)
            P = mre_update(P, sensor.jacobian(x_pred, nxt), sensor.R, pd)
        return mre_criterion(criterion, F @ P @ F.T + Q, x_pred)

    settings = SearchSettings(
        search=search,
        grid_size=grid_size,
        quadrant_divisions=divisions,
        quadrant_patience=patience,
        sector_levels=levels,
    )
    result = settings.lockstep_search()(cost_fn, 1)
    m, nxt, psi = candidates(result.u[0])
    return PositioningResult(m, nxt, float(psi), float(result.cost[0]), result.evaluations)
