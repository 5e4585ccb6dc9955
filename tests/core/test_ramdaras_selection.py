"""MRE sensor selection and positioning (Ramdaras et al. 2010, sec. 3-4, eq. 23-27)."""

import itertools
import math

import numpy as np
import pytest

from activetrack.bounds.costs import position_determinant, trace_cost
from activetrack.closed_loop.components import (
    build_planner,
    build_simulator,
    build_tracker,
    component_rngs,
)
from activetrack.models.motion import NearlyConstantVelocityDiscrete
from activetrack.models.sensors import (
    BearingSensor,
    RangeBearingSensor,
    RangeRateBearingSensor,
)
from activetrack.planning.manoeuvre import PlatformLimits, step_platform
from activetrack.planning.planner import PlannerPlatform
from activetrack.planning.selection import (
    TargetPrediction,
    expected_update,
    position_platform,
    select_by_criterion,
    select_by_trace,
    select_fixed,
    select_random,
    sensor_costs,
)
from activetrack_experiments.ramdaras import load_case, variant

SIGMA_B = math.sqrt(2.47e-6)  # Ramdaras sec. 5


def paper_sensors(pd=(1.0, 1.0, 1.0)):
    """s1, s2, s3 with R1, R2, R3 of sec. 5 (eq. 10 entry order: range, Doppler, bearing)."""
    return [
        BearingSensor(SIGMA_B, pd=pd[0]),
        RangeBearingSensor(math.sqrt(1000.0), SIGMA_B, pd=pd[1]),
        RangeRateBearingSensor(math.sqrt(60.0), 10.0, math.sqrt(2.47e-4), pd=pd[2]),
    ]


MODEL = NearlyConstantVelocityDiscrete(5.0, 5.0)
F = MODEL.transition_matrix(1.0)
Q = MODEL.process_noise(1.0)
P_PRED = F @ np.diag([100.0, 10.0, 100.0, 10.0]) @ F.T + Q
X_PRED = np.array([5000.0, 100.0, 0.0, 0.0])  # origin LOS along +x, course along +x
# A: all co-located 4 km behind the target on its course line.
GEOM_A = np.array([[1000.0, 0, 0, 0]] * 3)
# B: s3 moved to look across the target's course (LOS along y).
GEOM_B = np.array([[1000.0, 0, 0, 0], [1000.0, 0, 0, 0], [5000.0, 0, -4000.0, 0]])
# C: s1 1 km from the target, s2 and s3 4 km.
GEOM_C = np.array([[4000.0, 0, 0, 0], [1000.0, 0, 0, 0], [1000.0, 0, 0, 0]])
PREDICTION = TargetPrediction(X_PRED, P_PRED, F, Q)


def choice(criterion, geometry, sensors=None):
    sel = select_by_criterion(PREDICTION, sensors or paper_sensors(), geometry, criterion=criterion)
    return sel.selected[0] + 1, sel.costs


def test_costs_are_eq23_written_out():
    sensors = paper_sensors(pd=(1.0, 0.8, 0.6))
    pvs = GEOM_B
    costs, P_hat = sensor_costs(PREDICTION, sensors, pvs, "det_pos")
    for j, (s, pv) in enumerate(zip(sensors, pvs, strict=True)):
        H = s.jacobian(X_PRED, pv)
        S = H @ P_PRED @ H.T + s.R
        want = (
            F @ P_PRED @ F.T - s.pd * F @ P_PRED @ H.T @ np.linalg.inv(S) @ H @ P_PRED @ F.T + Q
        )  # eq. 23
        np.testing.assert_allclose(P_hat[j], want, rtol=1e-10, atol=1e-8)
        assert costs[j] == pytest.approx(want[0, 0] * want[2, 2] - want[0, 2] ** 2, rel=1e-10)


def test_one_look_is_the_expected_update_bit_for_bit():
    """``TargetPrediction.after_look`` (a planner's inner loop, nothing checked twice) gives
    the very covariance :func:`expected_update` gives, in range or not, and refuses a factor
    outside [0, 1]."""
    for sensor, pv, factor in zip(paper_sensors(), GEOM_C, (0.3, 0.8, 1.0), strict=True):
        got = PREDICTION.after_look(sensor, pv, factor)
        want = expected_update(P_PRED, X_PRED, [sensor], pv, detection=[factor])
        np.testing.assert_array_equal(got.P, want)
        np.testing.assert_array_equal(got.P, PREDICTION.with_covariance(want).P)
        assert got.x is PREDICTION.x and got.F is PREDICTION.F and got.P is not PREDICTION.P
    far = BearingSensor(SIGMA_B, r_max=100.0)  # the target is out of range: no update
    np.testing.assert_array_equal(PREDICTION.after_look(far, GEOM_A[0], 1.0).P, P_PRED)
    with pytest.raises(ValueError, match="pd must lie in"):
        PREDICTION.after_look(paper_sensors()[0], GEOM_A[0], 1.5)


def test_co_located_s2_dominates_s1_and_the_choice_alternates_with_s3():
    sensors = paper_sensors()
    # s2 = s1 plus a range: strictly better under eq. 24 wherever they share a position.
    costs, _ = sensor_costs(PREDICTION, sensors, GEOM_A, "det_pos")
    assert costs[1] < costs[0]
    # Selecting with the Kalman update of the pick, epoch after epoch, alternates s2 / s3.
    P, x, picks = P_PRED, X_PRED, []
    for _ in range(8):
        j = select_by_criterion(TargetPrediction(x, P, F, Q), sensors, GEOM_A).selected[0]
        picks.append(j + 1)
        P = F @ expected_update(P, x, [sensors[j]], GEOM_A[j]) @ F.T + Q
        x = F @ x
    assert 1 not in picks
    assert all(a != b for a, b in itertools.pairwise(picks)), picks


def test_range_criterion_picks_the_accurate_range_sensor():
    # Geometry A: det_pos prefers s2's bearing, the range criterion s3's 7.7 m range.
    assert choice("det_pos", GEOM_A)[0] == 2
    j, costs = choice("range", GEOM_A)
    assert j == 3 and costs[2] < 0.5 * costs[1]


def test_doppler_criterion_follows_the_line_of_sight():
    # Along the origin's LOS s3's Doppler measures the radial velocity directly ...
    j, costs = choice("doppler", GEOM_A)
    assert j == 3 and costs[2] < 0.9 * min(costs[:2])
    # ... across it (geometry B) it does not, and s2 wins.
    assert choice("doppler", GEOM_B)[0] == 2


def test_heading_criterion_wants_doppler_across_the_course():
    # B: s3 looks across the target's course, its Doppler is the cross-course velocity.
    j, costs = choice("heading", GEOM_B)
    assert j == 3 and costs[2] < 0.9 * min(costs[:2])
    assert choice("det_pos", GEOM_B)[0] == 2
    # A: s3's Doppler is along the course (speed, not heading): not chosen.
    assert choice("heading", GEOM_A)[0] != 3


def test_bearing_criterion_picks_the_closest_bearing_sensor():
    j, costs = choice("bearing", GEOM_C)
    assert j == 1 and costs[0] < 0.6 * costs[1]
    assert choice("range", GEOM_C)[0] == 3


def test_trace_baseline_ignores_pd_and_mre_does_not():
    # s3 detects one time in ten: the trace of the Kalman update still prefers it, eq. 23 not.
    sensors = paper_sensors(pd=(1.0, 1.0, 0.1))
    geom = np.array([[1000.0, 0, 0, 0], [1000.0, 0, 0, 0], [4990.0, 0, 0, 0]])
    trace = select_by_trace(PREDICTION, sensors, geom)
    mre = select_by_criterion(PREDICTION, sensors, geom, criterion="trace")
    assert trace.selected == (2,) and mre.selected != (2,)
    upd = expected_update(P_PRED, X_PRED, [sensors[2]], geom[2], use_pd=False)
    assert trace.costs[2] == pytest.approx(float(trace_cost(upd)))


def test_random_and_fixed_baselines():
    sensors = paper_sensors()
    draws = [
        select_random(PREDICTION, sensors, GEOM_A, np.random.default_rng(s)).selected[0]
        for s in range(60)
    ]
    assert set(draws) == {0, 1, 2}
    again = select_random(PREDICTION, sensors, GEOM_A, np.random.default_rng(0))
    assert again.selected[0] == draws[0]
    fixed = select_fixed(PREDICTION, sensors, GEOM_A, 0)
    assert fixed.selected == (0,)
    # Both report the MRE costs of every candidate for the record.
    mre_costs = sensor_costs(PREDICTION, sensors, GEOM_A, "det_pos")[0]
    np.testing.assert_array_equal(fixed.costs, mre_costs)
    with pytest.raises(ValueError, match="rng"):
        select_random(PREDICTION, sensors, GEOM_A, None)
    with pytest.raises(ValueError, match="index"):
        select_fixed(PREDICTION, sensors, GEOM_A, 3)
    with pytest.raises(ValueError, match="count"):
        select_by_criterion(PREDICTION, sensors, GEOM_A, count=4)
    with pytest.raises(ValueError, match="criterion must be one of"):
        select_by_criterion(PREDICTION, sensors, GEOM_A, criterion="rmse_bound")


def test_greedy_count_two_takes_the_best_pair():
    sensors = paper_sensors()
    sel = select_by_criterion(PREDICTION, sensors, GEOM_C, count=2)
    assert len(set(sel.selected)) == 2
    pair_cost = {}
    for a in range(3):
        for b in range(3):
            if a != b:
                P = expected_update(P_PRED, X_PRED, [sensors[a], sensors[b]], GEOM_C[[a, b]])
                pair_cost[(a, b)] = float(position_determinant(F @ P @ F.T + Q))
    best_first = sel.selected[0]
    assert sel.selected[0] == int(np.argmin(sel.costs))
    # The second pick is the best partner of the first.
    partners = {b: c for (a, b), c in pair_cost.items() if a == best_first}
    assert sel.selected[1] == min(partners, key=partners.get)


def test_sector_positioning_moves_a_bearing_sensor_towards_the_target():
    limits = PlatformLimits(math.pi / 20, 10.0, 50.0, 200.0)  # Ramdaras sec. 5, T = 1 s
    pv = np.array([4000.0, 0.0, 3000.0, 75.0])  # heading +y, away from the target
    heading, speed = math.pi / 2, 75.0
    s1 = paper_sensors()[0]
    platform = PlannerPlatform("p1", pv, (s1,), limits, heading=heading, speed=speed)
    res = position_platform(platform, PREDICTION, 1.0)  # sector search, d_max = 5
    assert res.evaluations == 16 + 12 * 4 + 1
    dpsi, v = res.manoeuvre
    assert abs(dpsi) <= limits.dpsi_max + 1e-12 and 65.0 - 1e-9 <= v <= 85.0 + 1e-9
    hold, _ = step_platform(pv, heading, np.array([0.0, speed]), 1.0)
    hold_cost, _ = sensor_costs(PREDICTION, [s1], hold, "det_pos")
    assert res.cost <= hold_cost[0]
    # Flying away from the target, it turns towards it (clockwise, dpsi < 0) at the slowest
    # reachable speed: the full turn and v_lo = 65 m/s lose the least range in one step.
    assert dpsi == pytest.approx(-limits.dpsi_max, rel=0.01) and v == pytest.approx(65.0, abs=0.1)
    d = lambda p: math.hypot(p[0] - X_PRED[0], p[2] - X_PRED[2])  # noqa: E731
    assert d(res.next_pv) < d(hold)


def test_stationary_platforms_hold_still_and_only_the_selection_measures():
    scenario = variant(load_case("case1_3_9"), "mre", steps=4)
    sim_rng, trk_rng, plan_rng, _ = component_rngs(scenario.seed, 0)
    sim, tracker = build_simulator(scenario, sim_rng), build_tracker(scenario, trk_rng)
    planner = build_planner(scenario, plan_rng)
    tracks = tracker.snapshot()
    for k in range(4):
        d = planner.decide(k, tracks, sim.platform_snapshots())
        assert d.commands == () and len(d.selected_sensor_ids) == 1
        assert d.candidate_sensor_ids == ("s1", "s2", "s3") and len(d.selection_costs) == 3
        sim.apply_selection(d.selected_sensor_ids)
        scans = sim.advance()
        assert [scan.sensor_id for scan in scans] == list(d.selected_sensor_ids)
        tracks = tracker.step(k + 1, sim.time, scans)
    for p in sim.platforms.values():
        np.testing.assert_array_equal(p.pv, [3000.0, 0.0, 9000.0, 0.0])
    snap = sim.platform_snapshots()[0]
    assert snap.speed == 0.0 and snap.heading == 0.0
