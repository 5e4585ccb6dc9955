"""Multi-step MRE positioning (Ramdaras sec. 7's future work): eq. 23 over R legs.

- R = 1 is the published one-step positioning, bit for bit (manoeuvre, position, cost,
  evaluations), for every search and several criteria on seeded random cases;
- R = 2's objective is the criterion after the second leg, recomputed independently with
  :func:`activetrack.bounds.mre.mre_recursion` along its plan; on a grid it is never above the
  one-step planner applied twice (its plan is one of the R = 2 candidates), and it is strictly
  lower where the benefit only shows two legs ahead (a sensor just beyond its maximum range);
- the closed-loop strategy flies the first manoeuvre of the R-leg plan; the scenario schema
  accepts R >= 2 with cost 'mre' and rejects searches that explode.
"""

import math

import numpy as np
import pytest

from activetrack.bounds.mre import mre_recursion, mre_update
from activetrack.closed_loop.components import build_strategies
from activetrack.data import CONFIRMED, PlatformSnapshot, TrackEstimate, TrackSet
from activetrack.models.motion import NearlyConstantVelocityDiscrete
from activetrack.models.sensors import BearingSensor, RangeBearingSensor
from activetrack.planning.criteria import get_criterion
from activetrack.planning.decision import DecisionContext, DecisionPart
from activetrack.planning.horizons import SearchSettings
from activetrack.planning.manoeuvre import (
    PlatformLimits,
    rollout,
    step_platform,
    unit_to_manoeuvre,
)
from activetrack.planning.planner import PlannerPlatform
from activetrack.planning.selection import (
    PositioningResult,
    TargetPrediction,
    expected_update,
    plan_positions,
    position_platform,
)
from activetrack.planning.strategies import MrePositioning
from activetrack.scenarios import ScenarioError, load_scenario, parse_scenario

MODEL = NearlyConstantVelocityDiscrete(5.0, 5.0)
F = MODEL.transition_matrix(1.0)
Q = MODEL.process_noise(1.0)
SIGMA_B = math.sqrt(2.47e-6)  # Ramdaras sec. 5
LIMITS = PlatformLimits(0.157, 10.0, 50.0, 200.0)
SEARCHES = (
    SearchSettings("sector", sector_levels=5),
    SearchSettings("quadrant"),
    SearchSettings("grid", grid_size=21),
)


def _random_case(rng, n_sensors):
    x = np.array([rng.uniform(0, 5000), rng.uniform(-100, 100)] * 2)
    x[2], x[3] = rng.uniform(0, 5000), rng.uniform(-100, 100)
    prediction = TargetPrediction.from_posterior(x, np.diag(rng.uniform(50, 500, 4)), F, Q)
    heading = rng.uniform(-math.pi, math.pi)
    pv = np.array([rng.uniform(-3000, 8000), 0.0, rng.uniform(-3000, 8000), 0.0])
    pv[1], pv[3] = 100.0 * math.cos(heading), 100.0 * math.sin(heading)
    sensors = (BearingSensor(SIGMA_B, pd=0.9), RangeBearingSensor(30.0, SIGMA_B, pd=0.8))
    return PlannerPlatform("p", pv, sensors[:n_sensors], LIMITS), prediction


def _one_step(platform, prediction, criterion, search):
    """Ramdaras sec. 4's one-step positioning written out: ``search`` over the reachable
    envelope, a candidate's cost eq. 23 with the platform's sensors there, then ``criterion``."""
    crit = get_criterion(criterion)
    p, (heading, speed) = prediction, platform.heading_and_speed

    def candidates(u):
        m = unit_to_manoeuvre(u, speed, platform.limits)
        nxt, psi = step_platform(platform.pv, heading, m, 1.0)
        return m, nxt, psi

    def cost_fn(rows, u):
        _, nxt, _ = candidates(u)
        P = p.P
        for sensor in platform.sensors:
            pd = float(sensor.pd) * sensor.in_range(p.x, nxt)
            P = mre_update(P, sensor.jacobian(p.x, nxt), sensor.R, pd)
        return crit.of_covariance(p.F @ P @ p.F.T + p.Q, p.x)

    result = search.lockstep_search()(cost_fn, 1)
    m, nxt, psi = candidates(result.u[0])
    return PositioningResult(m, nxt, float(psi), float(result.cost[0]), result.evaluations)


def test_one_leg_is_the_one_step_positioning_bit_for_bit():
    rng = np.random.default_rng(3)
    for case in range(4):
        platform, prediction = _random_case(rng, 1 + case % 2)
        for search in SEARCHES:
            for criterion in ("det_pos", "trace", "heading"):
                a = _one_step(platform, prediction, criterion, search)
                b = plan_positions(
                    platform, prediction, 1.0, criterion=criterion, search=search, horizon=1
                )
                assert np.array_equal(a.manoeuvre, b.manoeuvre)
                assert np.array_equal(a.next_pv, b.next_pv)
                assert (a.cost, a.heading, a.evaluations) == (b.cost, b.heading, b.evaluations)
                assert b.plan.shape == (1, 2)


def _greedy_twice(platform, prediction, search):
    """The one-step planner at k, then again at k+1 from the expected update: its criterion
    after the second leg (P_{k+3|k+2}) and the first manoeuvre."""
    first = position_platform(platform, prediction, 1.0, search=search)
    P_upd = expected_update(prediction.P, prediction.x, platform.sensors, first.next_pv[None])
    following = TargetPrediction.from_posterior(prediction.x, P_upd, F, Q)  # x: F x_{k+1|k}
    moved = PlannerPlatform("p", first.next_pv, platform.sensors, LIMITS)
    return position_platform(moved, following, 1.0, search=search).cost, first.manoeuvre


def _replayed(platform, prediction, plan):
    """det_pos after the plan's last leg, by the bounds module's eq. 23 recursion."""
    path, _ = rollout(platform.pv, platform.heading, plan, 1.0)
    P = mre_recursion(prediction.P, F, Q, list(platform.sensors), prediction.x, path[:, None])
    x_last = np.linalg.matrix_power(F, len(plan) - 1) @ prediction.x
    return float(get_criterion("det_pos").of_covariance(P[-1], x_last))


def test_two_legs_never_above_the_one_step_planner_twice():
    grid = SearchSettings("grid", grid_size=11)
    rng = np.random.default_rng(11)
    for _ in range(6):
        platform, prediction = _random_case(rng, 1)
        two = plan_positions(platform, prediction, 1.0, search=grid, horizon=2)
        greedy, _ = _greedy_twice(platform, prediction, grid)
        assert two.cost <= greedy * (1.0 + 1e-12)
        assert two.cost == pytest.approx(_replayed(platform, prediction, two.plan), rel=1e-12)
        assert two.evaluations == 121 + 121 * 121  # a grid per leg, nested


def test_two_legs_see_the_maximum_range_the_one_step_planner_cannot():
    # A stationary target 5.2 km away, a range-bearing sensor reaching 5 km, the platform
    # heading at it at 100 m/s (at most 110 m per leg): no candidate of the first leg comes in
    # range, so the one-step planner's costs tie and it takes the search's first point (hard
    # right, slowest), which cannot reach the range the leg after either. Two legs see it.
    prediction = TargetPrediction.from_posterior(np.zeros(4), np.diag([1e4, 1.0, 1e4, 1.0]), F, Q)
    sensor = RangeBearingSensor(30.0, 0.01, pd=0.9, r_max=5000.0)
    limits = PlatformLimits(0.6, 10.0, 50.0, 200.0)
    platform = PlannerPlatform("p", np.array([5200.0, -100.0, 0.0, 0.0]), (sensor,), limits)
    grid = SearchSettings("grid", grid_size=11)
    two = plan_positions(platform, prediction, 1.0, search=grid, horizon=2)
    greedy, first = _greedy_twice(platform, prediction, grid)
    assert first.tolist() == pytest.approx([-0.6, 90.0])
    assert two.manoeuvre.tolist() == pytest.approx([0.0, 110.0])  # straight at it, fastest
    assert two.cost == pytest.approx(_replayed(platform, prediction, two.plan), rel=1e-12)
    path, _ = rollout(platform.pv, platform.heading, two.plan, 1.0)
    assert np.hypot(path[:, 0], path[:, 2]).tolist() == pytest.approx([5090.0, 4970.0])
    # The one-step planner twice never measures: its det_pos [m^4] after two legs is that of
    # the bare prediction F (F P F^T + Q) F^T + Q, 1.046e8; two legs get a range-bearing
    # update at k+2 and 5.25e6, 20 times lower.
    P = F @ (F @ prediction.P @ F.T + Q) @ F.T + Q
    assert greedy == pytest.approx(P[0, 0] * P[2, 2] - P[0, 2] ** 2, rel=1e-12)
    assert greedy == pytest.approx(1.046e8, rel=1e-3)
    assert two.cost == pytest.approx(5.25e6, rel=1e-3)


def _case3(**planner):
    data = load_scenario("scenarios/ramdaras_case3_pd.yaml").model_dump()
    data["planner"].update(planner)
    return parse_scenario(data, "case3")


def test_the_strategy_flies_the_first_manoeuvre_of_the_r_leg_plan():
    scenario = _case3(horizon=2, sector_levels=3)
    strategies = build_strategies(scenario, np.random.default_rng(0))
    strategy = next(s for s in strategies if isinstance(s, MrePositioning))
    prior = scenario.target.prior
    prediction = TargetPrediction.from_posterior(prior.mean, prior.covariance(), F, Q)
    snaps = {}
    for p in scenario.platforms:
        pv = np.array(p.initial_state)
        heading, speed = math.atan2(pv[3], pv[1]), math.hypot(pv[1], pv[3])
        snaps[p.id] = PlatformSnapshot(p.id, 0, 0.0, pv, heading, speed)
    mean, cov = np.array(prior.mean), prior.covariance()
    track = TrackEstimate(1, CONFIRMED, mean, cov, mean, cov, origin="t1")
    part = strategy.decide(
        DecisionContext(
            0,
            TrackSet(0, 0.0, "ekf", tracks=(track,)),
            snaps,
            1.0,
            DecisionPart(prediction=prediction),
        )
    )
    search = SearchSettings("sector", sector_levels=3)
    for command, (pid, limits, models) in zip(part.commands, strategy.platforms, strict=True):
        s = snaps[pid]
        platform = PlannerPlatform(pid, s.pv, models, limits, heading=s.heading, speed=s.speed)
        want = plan_positions(platform, prediction, 1.0, search=search, horizon=2)
        assert command.heading_change == want.manoeuvre[0]
        assert command.commanded_speed == want.manoeuvre[1]
        assert part.extra["positioning_costs"][pid] == want.cost
        assert part.planned_pv[pid].tolist() == want.next_pv.tolist()


def test_schema_accepts_mre_horizons_and_rejects_exploding_searches():
    assert _case3(horizon=3).planner.horizon == 3  # sector d_max 5: 65^3 evaluations
    with pytest.raises(ScenarioError, match=r"search 'sector' with cost 'mre' and horizon 4"):
        _case3(horizon=4)  # 65^4 = 1.8e7 > 1e7
    with pytest.raises(ScenarioError, match=r"search 'grid' with cost 'mre' and horizon 2"):
        _case3(horizon=2, search="grid")  # 101 x 101 per leg
