"""Horizons (single step, two-step DP, R-step evolution), several platforms, limits, inputs."""

import itertools
import math

import numpy as np
import pytest

from activetrack.bounds import (
    covariance_bound,
    pcrlb_trajectory,
    propagate_samples,
    rmse_bound,
    rmse_bound_of_information,
)
from activetrack.models.motion import NearlyConstantVelocity
from activetrack.models.sensors import BearingSensor
from activetrack.planning import (
    PlannerPlatform,
    PlanSettings,
    PlatformLimits,
    SearchSettings,
    TargetBelief,
    advance_belief,
    plan,
    rollout,
    speed_interval,
    unit_to_manoeuvre,
)

DT = 5.0
MODEL = NearlyConstantVelocity(q=1e-8)
F, Q = MODEL.transition_matrix(DT), MODEL.process_noise(DT)
LIMITS = PlatformLimits(np.pi / 10, 10.0, 50.0, 200.0)
SENSOR = BearingSensor(0.01, r_min=1000.0)
STARTS = {
    "p1": [1800.0, -40.0, 2000.0, -40.0],  # Hernandez eq. 17-19
    "p2": [2000.0, -40.0, 2000.0, -40.0],
    "p3": [1600.0, -40.0, 2000.0, -40.0],
}


def belief(n_samples=300, seed=11):
    return TargetBelief.from_gaussian(
        [1000.0, -40.0, 1000.0, -40.0],
        np.diag([10.0, 1.0, 10.0, 1.0]),
        n_samples,
        np.random.default_rng(seed),
    )


def platforms(ids=("p1",)):
    return [PlannerPlatform(i, np.array(STARTS[i]), (SENSOR,), LIMITS) for i in ids]


def settings(search="quadrant", horizon=1, **kw):
    return PlanSettings(horizon=horizon, search=SearchSettings(search=search, **kw))


def test_two_step_dp_equals_brute_force_on_a_small_grid():
    n = 5
    b = belief()
    (p,) = platforms()
    res = plan([p], b, settings("grid", 2, grid_size=n), F=F, Q=Q, dt=DT)
    samples = propagate_samples(b.samples, F, Q, 2)  # noise-free, as plan() with rng=None
    g = np.linspace(0.0, 1.0, n)
    units = np.array(list(itertools.product(g, g)))  # (n^2, 2)
    m1 = unit_to_manoeuvre(units, p.speed, LIMITS)  # (n^2, 2)
    m2 = unit_to_manoeuvre(units[None, :, :], m1[:, None, 1], LIMITS)  # (n^2, n^2, 2)
    seqs = np.stack(np.broadcast_arrays(m1[:, None, :], m2), axis=2)  # (n^2, n^2, 2 steps, 2)
    path, _ = rollout(p.pv, p.heading, seqs, DT)  # (n^2, n^2, 2, 4)
    J = pcrlb_trajectory(b.J, F, Q, samples, SENSOR, np.moveaxis(path, 2, 0))
    total = np.sum(rmse_bound(covariance_bound(J)), axis=0)  # b_{k+1} + b_{k+2}, all pairs
    i, j = np.unravel_index(np.argmin(total), total.shape)
    best, best_plan = total[i, j], seqs[i, j]
    assert res.report.objective == pytest.approx(best, rel=1e-10)
    np.testing.assert_allclose(res.manoeuvres[0].plan, best_plan, atol=1e-12)
    assert res.report.evaluations == n * n + (n * n) ** 2


def test_r_step_with_r_1_equals_single_step():
    b = belief()
    ps = platforms()
    fine = plan(ps, b, settings("grid", 1, grid_size=101), F=F, Q=Q, dt=DT)
    evo = plan(
        ps,
        b,
        settings("evolution", 1, evolution_popsize=10, evolution_maxiter=60),
        F=F,
        Q=Q,
        dt=DT,
        rng=np.random.default_rng(5),
    )
    assert evo.report.objective <= fine.report.objective * (1 + 1e-3)
    # The single-step objective is b_{k+1} itself (eq. 11).
    assert evo.report.objective == pytest.approx(evo.report.predicted["b_k"], rel=1e-12)
    m_evo, m_grid = evo.manoeuvres[0], fine.manoeuvres[0]
    assert abs(m_evo.heading_change - m_grid.heading_change) < 0.02
    assert abs(m_evo.speed - m_grid.speed) < 0.5


def test_r_step_evolution_is_at_least_as_good_as_two_step_quadrant_dp():
    b = belief()
    ps = platforms()
    dp = plan(ps, b, settings("quadrant", 2), F=F, Q=Q, dt=DT)
    evo = plan(
        ps,
        b,
        settings("evolution", 2, evolution_maxiter=80),
        F=F,
        Q=Q,
        dt=DT,
        rng=np.random.default_rng(2),
    )
    assert evo.report.objective <= dp.report.objective * (1 + 2e-3)
    assert evo.manoeuvres[0].plan.shape == (2, 2)


@pytest.mark.parametrize("horizon", [1, 2])
def test_multi_sensor_iteration_converges_to_a_fixed_point(horizon):
    b = belief(200)
    ps = platforms(("p1", "p2", "p3"))
    res = plan(ps, b, settings("quadrant", horizon), F=F, Q=Q, dt=DT)
    assert res.report.converged
    assert 2 <= res.report.iterations <= 10
    if horizon == 2:
        return
    # Fixed point: each platform's manoeuvre is its best reply to the others' manoeuvres.
    chosen = {m.platform_id: m for m in res.manoeuvres}
    for p in ps:
        others = [
            PlannerPlatform(q.platform_id, _leg_pv(q, chosen[q.platform_id]), q.sensors)
            for q in ps
            if q.platform_id != p.platform_id
        ]
        alone = plan([p, *others], b, settings("quadrant", 1), F=F, Q=Q, dt=DT)
        m = alone.manoeuvre(p.platform_id)
        assert m.heading_change == pytest.approx(chosen[p.platform_id].heading_change, abs=1e-12)
        assert m.speed == pytest.approx(chosen[p.platform_id].speed, abs=1e-9)


def _leg_pv(p, m):
    """pv at epoch k whose constant-velocity leg is the manoeuvred leg (a non-controllable
    platform holds course along its pv velocity)."""
    return np.array([p.pv[0], m.next_pv[1], p.pv[2], m.next_pv[3]])


@pytest.mark.parametrize(
    ("search", "horizon"), [("quadrant", 1), ("sector", 1), ("grid", 1), ("quadrant", 2)]
)
def test_manoeuvre_limits_respected_along_an_open_loop_run(search, horizon):
    b = belief(200)
    ps = platforms(("p1", "p2"))
    s = settings(search, horizon, grid_size=15)
    for _ in range(6):
        res = plan(ps, b, s, F=F, Q=Q, dt=DT)
        nxt = []
        for p in ps:
            m = res.manoeuvre(p.platform_id)
            lo, hi = speed_interval(p.speed, LIMITS)
            assert abs(m.heading_change) <= LIMITS.dpsi_max + 1e-12
            assert lo - 1e-9 <= m.speed <= hi + 1e-9
            assert LIMITS.v_min - 1e-9 <= m.speed <= LIMITS.v_max + 1e-9
            assert abs(m.speed_change) <= LIMITS.dv_max + 1e-9
            assert math.hypot(m.next_pv[1], m.next_pv[3]) == pytest.approx(m.speed)
            for dpsi, v in m.plan:  # the whole planned horizon, too
                assert abs(dpsi) <= LIMITS.dpsi_max + 1e-12
                assert LIMITS.v_min - 1e-9 <= v <= LIMITS.v_max + 1e-9
            nxt.append(PlannerPlatform(p.platform_id, m.next_pv, p.sensors, p.limits))
        b = advance_belief(b, nxt, F, Q)
        ps = nxt


def test_prediction_matches_advance_belief_and_renewal_from_particles():
    b = belief()
    ps = platforms(("p1", "p2"))
    res = plan(ps, b, settings(), F=F, Q=Q, dt=DT)
    moved = [
        PlannerPlatform(p.platform_id, res.manoeuvre(p.platform_id).next_pv, p.sensors, p.limits)
        for p in ps
    ]
    nxt = advance_belief(b, moved, F, Q)
    np.testing.assert_allclose(res.J_next, nxt.J, rtol=1e-10)
    # Renewal: unweighted particles give back their covariance's inverse and themselves.
    X = b.samples
    r = TargetBelief.from_particles(X)
    np.testing.assert_allclose(np.linalg.inv(r.J), np.cov(X.T, bias=True), rtol=1e-8)
    np.testing.assert_array_equal(r.samples, X)
    w = np.random.default_rng(0).random(len(X))
    r = TargetBelief.from_particles(X, w, n_samples=50, rng=np.random.default_rng(1))
    assert r.samples.shape == (50, 4)


def test_ramdaras_limits_map_to_per_epoch_limits():
    from activetrack.scenarios.build import platform_limits
    from activetrack.scenarios.schema import ManoeuvreLimits

    cfg = ManoeuvreLimits(a_max=2.0, psi_rate_max=0.05, v_min=5.0, v_max=15.0)
    lim = platform_limits(cfg, 5.0)
    assert (lim.dpsi_max, lim.dv_max, lim.v_min, lim.v_max) == (0.25, 10.0, 5.0, 15.0)
    lo, hi = speed_interval(12.0, lim)
    assert (float(lo), float(hi)) == (5.0, 15.0)
    m = unit_to_manoeuvre(np.array([[0.0, 0.0], [1.0, 1.0], [0.5, 0.5]]), 12.0, lim)
    np.testing.assert_allclose(m, [[-0.25, 5.0], [0.25, 15.0], [0.0, 10.0]])


def test_rollout_flies_constant_velocity_legs():
    pv = np.array([0.0, 10.0, 0.0, 0.0])
    path, headings = rollout(pv, 0.0, np.array([[np.pi / 2, 20.0], [0.0, 30.0]]), 2.0)
    np.testing.assert_allclose(path[0], [0.0, 0.0, 40.0, 20.0], atol=1e-12)
    np.testing.assert_allclose(path[1], [0.0, 0.0, 100.0, 30.0], atol=1e-12)
    np.testing.assert_allclose(headings, [np.pi / 2, np.pi / 2])


def test_bad_planner_inputs_raise_value_error_naming_the_argument():
    b = belief(50)
    ps = platforms()
    s = settings()
    with pytest.raises(ValueError, match="platforms"):
        plan([], b, s, F=F, Q=Q, dt=DT)
    with pytest.raises(ValueError, match="belief"):
        plan(ps, object(), s, F=F, Q=Q, dt=DT)
    with pytest.raises(ValueError, match="settings"):
        plan(ps, b, object(), F=F, Q=Q, dt=DT)
    with pytest.raises(ValueError, match="F"):
        plan(ps, b, s, F=np.eye(3), Q=Q, dt=DT)
    with pytest.raises(ValueError, match="Q"):
        plan(ps, b, s, F=F, Q=-np.eye(4), dt=DT)
    with pytest.raises(ValueError, match="dt"):
        plan(ps, b, s, F=F, Q=Q, dt=0.0)
    with pytest.raises(ValueError, match="rng"):
        plan(ps, b, s, F=F, Q=Q, dt=DT, rng=3)
    with pytest.raises(ValueError, match="platforms"):
        plan([ps[0], ps[0]], b, s, F=F, Q=Q, dt=DT)
    with pytest.raises(ValueError, match="belief.J"):
        TargetBelief(-np.eye(4), b.samples)
    with pytest.raises(ValueError, match="belief.samples"):
        TargetBelief(b.J, np.zeros((10, 3)))
    with pytest.raises(ValueError, match="platforms.pv"):
        PlannerPlatform("x", np.array([0.0, np.nan, 0.0, 0.0]), (SENSOR,), LIMITS)
    with pytest.raises(ValueError, match="platforms.heading"):
        PlannerPlatform("x", np.zeros(4), (SENSOR,), LIMITS)
    with pytest.raises(ValueError, match="platforms.sensors"):
        PlannerPlatform("x", np.array(STARTS["p1"]), (), LIMITS)
    with pytest.raises(ValueError, match="limits.dv_max"):
        PlatformLimits(0.3, -1.0, 50.0, 200.0)
    with pytest.raises(ValueError, match="limits"):
        PlatformLimits(0.3, 1.0, 300.0, 200.0)
    with pytest.raises(ValueError, match="horizon"):
        PlanSettings(horizon=0)
    with pytest.raises(ValueError, match="criterion"):
        PlanSettings(criterion="heading")
    with pytest.raises(ValueError, match="search"):
        SearchSettings(search="cautious")
    with pytest.raises(ValueError, match="grid_size"):
        SearchSettings(grid_size=1)
    from activetrack.scenarios.build import plan_settings
    from activetrack.scenarios.schema import PlannerConfig

    with pytest.raises(ValueError, match="planner.cost"):
        plan_settings(PlannerConfig(cost="mre"))
    with pytest.raises(ValueError, match="overrides"):
        plan_settings(PlannerConfig(), bogus=1)


@pytest.mark.parametrize("criterion", ["trace", "det_pos"])
def test_other_criteria_plan_and_are_consistent_with_their_definition(criterion):
    b = belief(200)
    res = plan(platforms(), b, PlanSettings(criterion=criterion), F=F, Q=Q, dt=DT)
    assert res.report.objective == pytest.approx(res.report.predicted[criterion], rel=1e-10)


def test_rmse_bound_of_information_equals_eq10_on_the_inverse():
    rng = np.random.default_rng(7)
    A = rng.normal(size=(6, 5, 4, 4))
    J = A @ np.swapaxes(A, -1, -2) + 1e-3 * np.eye(4)
    np.testing.assert_allclose(
        rmse_bound_of_information(J), rmse_bound(covariance_bound(J)), rtol=1e-10
    )
    with pytest.raises(ValueError, match="J must be symmetric positive definite"):
        rmse_bound_of_information(np.zeros((4, 4)))
