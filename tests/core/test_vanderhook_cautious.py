"""Beta-cautious planner API and bounds (Vander Hook, Tokekar, Isler (003), sec. II-IV)."""

import math
from statistics import NormalDist

import numpy as np
import pytest

from activetrack.filters import ExtendedKalmanFilter, Measurement
from activetrack.models.motion import NearlyConstantVelocity
from activetrack.models.sensors import AmbiguousBearingSensor
from activetrack.planning.cautious import (
    CautiousPlanner,
    ambiguous_bearing_update,
    caution_gamma,
    cautious_range,
    measurement_waypoint,
    principal_axes,
    reduction_reached,
    sigma_beta,
)
from activetrack.planning.cautious_bounds import (
    alternating_measurements,
    cautious_schedule,
    distance_bound,
    lemma4_measurements,
    time_lower_bound,
    time_upper_bound,
)
from activetrack_experiments.vanderhook_sim import simulate_localisation

SIGMA_S = math.radians(15.0)
PHI = NormalDist().cdf


@pytest.mark.parametrize("beta", [0.01, 0.1, 0.5, 0.9])
def test_sigma_beta_two_sided_tail_probability_is_beta(beta):
    # P(|y| > pi/2) for y ~ N(0, sigma_beta^2) equals beta (eq. 2 and the line after eq. 3).
    sb = sigma_beta(beta)
    assert 2.0 * (1.0 - PHI(0.5 * math.pi / sb)) == pytest.approx(beta, rel=1e-9)


def test_sigma_beta_one_sided_and_limits():
    sb = sigma_beta(0.1, "one_sided")
    assert 1.0 - PHI(0.5 * math.pi / sb) == pytest.approx(0.1, rel=1e-9)
    assert sigma_beta(0.1) == pytest.approx(math.pi / (2 * 1.6448536269514722), rel=1e-12)
    assert math.isinf(sigma_beta(0.5, "one_sided"))
    for bad in (0.0, 1.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="beta"):
            sigma_beta(bad)
    with pytest.raises(ValueError, match="beta"):
        sigma_beta(0.6, "one_sided")
    with pytest.raises(ValueError, match="tail"):
        sigma_beta(0.1, "both")
    # sigma_s must be below sigma_beta (sec. III).
    with pytest.raises(ValueError, match="sigma_s"):
        caution_gamma(1e-9, SIGMA_S)


def test_cautious_range_makes_innovation_variance_sigma_beta_squared():
    # At the range of eq. 3, S = H P H^T + sigma_s^2 equals sigma_beta^2 for any alpha.
    P = np.array([[900.0, 300.0], [300.0, 400.0]])
    var, major = principal_axes(P)
    for alpha in (0.3, 0.5 * math.pi, 2.0):
        r = float(cautious_range(P, alpha, 0.1, SIGMA_S))
        phi = math.atan2(major[1], major[0]) + alpha
        sensor = -r * np.array([math.cos(phi), math.sin(phi)])  # x_hat = 0 seen from sensor
        upd = ambiguous_bearing_update(np.zeros(2), P, 0.0, sensor, SIGMA_S)
        assert upd.S == pytest.approx(sigma_beta(0.1) ** 2, rel=1e-9)
    # alpha = pi/2: Algorithm 1 line 6.
    expected = math.sqrt(var[0] / (sigma_beta(0.1) ** 2 - SIGMA_S**2))
    assert float(cautious_range(P, 0.5 * math.pi, 0.1, SIGMA_S)) == pytest.approx(expected)


def test_cautious_step_divides_major_variance_by_gamma_and_keeps_axes():
    # Lemma 1 and the proof of Lemma 4: measuring from (r_i, pi/2) gives sigma'^2(1) =
    # sigma^2(1) / gamma, leaves sigma^2(2) and the eigenvectors unchanged.
    theta = 0.4
    R = np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])
    P = R @ np.diag([2500.0, 400.0]) @ R.T
    x_hat = np.array([10.0, -5.0])
    r = cautious_range(P, 0.5 * math.pi, 0.1, SIGMA_S)
    s = measurement_waypoint(x_hat, P, np.array([300.0, 200.0]), r)
    upd = ambiguous_bearing_update(x_hat, P, 1.0, s, SIGMA_S)
    var, major = principal_axes(upd.cov)
    gamma = caution_gamma(0.1, SIGMA_S)
    assert sorted(var) == pytest.approx(sorted([2500.0 / gamma, 400.0]), rel=1e-9)
    new_major_dir = R[:, 1]  # the old minor axis is now the major one
    assert abs(float(major @ new_major_dir)) == pytest.approx(1.0, abs=1e-9)
    # The estimate moves only along the reduced (old major) axis.
    assert float((upd.mean - x_hat) @ R[:, 1]) == pytest.approx(0.0, abs=1e-9)


def test_waypoint_is_perpendicular_to_major_axis_on_the_robot_side():
    P = np.diag([900.0, 100.0])  # major axis x
    x_hat = np.array([5.0, 5.0])
    s_up = measurement_waypoint(x_hat, P, np.array([0.0, 80.0]), 30.0)
    s_down = measurement_waypoint(x_hat, P, np.array([0.0, -80.0]), 30.0)
    assert s_up == pytest.approx([5.0, 35.0])
    assert s_down == pytest.approx([5.0, -25.0])
    # Circular prior: the closest cautious point, on the segment towards the robot.
    s = measurement_waypoint(np.zeros(2), 100.0 * np.eye(2), np.array([30.0, 40.0]), 10.0)
    assert s == pytest.approx([6.0, 8.0])
    # Batched.
    batch = measurement_waypoint(
        np.zeros((3, 2)), np.tile(P, (3, 1, 1)), np.array([[0, 1], [0, -1], [1, 1]]), np.ones(3)
    )
    assert batch == pytest.approx(np.array([[0, 1], [0, -1], [0, 1]]))


def test_ambiguous_update_matches_library_ekf_and_is_branch_invariant():
    x_hat, P = np.array([3.0, -2.0]), np.array([[400.0, 50.0], [50.0, 200.0]])
    s = np.array([40.0, 25.0])
    truth_bearing = math.atan2(-2.0 - 25.0, 3.0 - 40.0) + 0.2
    sensor_pv = np.array([s[0], 0.0, s[1], 0.0])
    z = float(AmbiguousBearingSensor(SIGMA_S).measure([4.0, 0, -2.0, 0], sensor_pv)[0])
    for zz in (truth_bearing, truth_bearing + math.pi, truth_bearing - math.pi, z):
        upd = ambiguous_bearing_update(x_hat, P, zz, s, SIGMA_S)
        ekf = ExtendedKalmanFilter(
            NearlyConstantVelocity(0.0),
            np.array([x_hat[0], 0.0, x_hat[1], 0.0]),
            np.diag([P[0, 0], 1e-6, P[1, 1], 1e-6])
            + np.array([[0, 0, P[0, 1], 0], [0, 0, 0, 0], [P[0, 1], 0, 0, 0], [0, 0, 0, 0]]),
        )
        ekf.update([Measurement(AmbiguousBearingSensor(SIGMA_S), sensor_pv, np.array([zz]), 0.0)])
        assert upd.mean == pytest.approx(ekf.mean[[0, 2]], abs=1e-9)
        assert upd.cov == pytest.approx(ekf.cov[np.ix_([0, 2], [0, 2])], rel=1e-9)
    a = ambiguous_bearing_update(x_hat, P, truth_bearing, s, SIGMA_S)
    b = ambiguous_bearing_update(x_hat, P, truth_bearing + math.pi, s, SIGMA_S)
    assert a.mean == pytest.approx(b.mean)
    # The chosen bearing is the one within pi/2 of the prediction.
    predicted = math.atan2(x_hat[1] - s[1], x_hat[0] - s[0])
    assert abs(math.remainder(float(a.bearing) - predicted, 2 * math.pi)) < 0.5 * math.pi
    expected_y = (truth_bearing - predicted + 0.5 * math.pi) % math.pi - 0.5 * math.pi
    assert float(a.innovation) == pytest.approx(expected_y)
    assert float(b.innovation) == pytest.approx(expected_y)


def test_ambiguous_update_rejects_bad_input():
    P = np.eye(2)
    with pytest.raises(ValueError, match="range"):
        ambiguous_bearing_update(np.zeros(2), P, 0.0, np.zeros(2), SIGMA_S)
    with pytest.raises(ValueError, match="P"):
        ambiguous_bearing_update(np.zeros(2), -P, 0.0, np.ones(2), SIGMA_S)
    with pytest.raises(ValueError, match="sigma_s"):
        ambiguous_bearing_update(np.zeros(2), P, 0.0, np.ones(2), 0.0)
    with pytest.raises(ValueError, match="z"):
        ambiguous_bearing_update(np.zeros(2), P, float("nan"), np.ones(2), SIGMA_S)


def test_reduction_rule():
    P0 = np.diag([100.0, 25.0])
    # Thresholds c_d^2 * (100, 25) = (1, 0.25) on the sorted eigenvalues.
    assert not reduction_reached(np.diag([1.01, 0.2]), P0, 0.1)
    assert not reduction_reached(np.diag([0.99, 0.26]), P0, 0.1)
    assert reduction_reached(np.diag([0.24, 0.99]), P0, 0.1)
    with pytest.raises(ValueError, match="c_d"):
        reduction_reached(P0, P0, 1.0)


def test_planner_api_with_pv_inputs():
    P0 = np.diag([3600.0, 1e-6, 3600.0, 1e-6])
    planner = CautiousPlanner(sigma_s=SIGMA_S, prior_cov=P0, beta=0.1, c_d=0.1, t_m=60.0)
    action = planner.next_action(np.zeros(4), P0, np.array([100.0, 0.0, 0.0, 0.0]))
    r1 = 60.0 / math.sqrt(sigma_beta(0.1) ** 2 - SIGMA_S**2)
    assert not action.done
    assert action.waypoint == pytest.approx([r1, 0.0])
    assert action.travel == pytest.approx(100.0 - r1)
    assert action.range == pytest.approx(r1)
    assert action.dwell == 60.0
    upd = planner.update(np.zeros(4), P0, math.pi, np.array([r1, 0.0, 0.0, 0.0]))
    assert upd.cov[1, 1] == pytest.approx(3600.0 / planner.gamma)
    assert planner.next_action(np.zeros(2), 30.0 * np.eye(2), np.zeros(2)).done
    assert planner.next_action(np.zeros(2), 40.0 * np.eye(2), np.ones(2), 7).waypoint is not None
    capped = CautiousPlanner(sigma_s=SIGMA_S, prior_cov=P0, max_measurements=3)
    assert capped.next_action(np.zeros(2), 3600.0 * np.eye(2), np.ones(2), 3).done
    with pytest.raises(ValueError, match="prior_cov"):
        CautiousPlanner(sigma_s=SIGMA_S, prior_cov=np.eye(3))
    with pytest.raises(ValueError, match="r_min"):
        CautiousPlanner(sigma_s=SIGMA_S, prior_cov=np.eye(2), beta=0.5, tail="one_sided")
    with pytest.raises(ValueError, match="robot_position"):
        planner.next_action(np.zeros(2), np.eye(2) * 3600, np.zeros(3))


def test_measurement_counts_and_closed_forms():
    # Sec. V worked example: c_d = 6 / 50, beta = 0.1 gives N = 4.
    assert lemma4_measurements(0.1, SIGMA_S, 0.12) == 4
    assert alternating_measurements(0.1, SIGMA_S, 0.12) == 4
    # Lemma 4's single ceiling is one short for c_d = 0.25 (gamma = 13.3 < 16).
    assert lemma4_measurements(0.1, SIGMA_S, 0.25) == 3
    assert alternating_measurements(0.1, SIGMA_S, 0.25) == 4
    for c_d in (0.25, 0.12, 0.1, 0.01):
        sched = cautious_schedule(3600.0 * np.eye(2), 0.1, SIGMA_S, c_d)
        assert sched.n_measurements == alternating_measurements(0.1, SIGMA_S, c_d)
        assert np.all(np.sqrt(sched.variances) < c_d * 60.0)
    # eq. 4 by hand (gamma from beta = 0.1, two-sided).
    g = caution_gamma(0.1, SIGMA_S)
    by_hand = 7.0 + 2 * 60 * 0.9 / (math.sqrt(g) - 1) * (
        (math.sqrt(2) + math.pi * (g - 1) / g) / (SIGMA_S * math.sqrt(g - 1))
    )
    assert distance_bound(60.0, 0.1, SIGMA_S, 0.1, 7.0) == pytest.approx(by_hand)
    assert time_upper_bound(4, 60.0, 100.0) == pytest.approx(340.0)
    # eq. 6: standoff sigma^2 / (2 t_m (1/c^2 - 1) sigma_s^2).
    standoff = 3600.0 / (2 * 60.0 * 99.0 * SIGMA_S**2)
    lb = time_lower_bound(np.array([100.0, 1.0]), 60.0, 60.0, 0.1, SIGMA_S)
    assert lb == pytest.approx([100.0 - standoff + 60.0, 60.0])


@pytest.mark.parametrize("beta,tail", [(0.1, "two_sided"), (0.5, "one_sided"), (0.01, "two_sided")])
def test_simulation_respects_schedule_and_travel_bound(beta, tail):
    # Invariants per run: N equals the covariance-only schedule; the distance travelled never
    # exceeds Lemma 5's per-leg bound; the EKF covariance is independent of the measurements.
    runs = simulate_localisation(
        500, np.random.default_rng(5), r0_hat=100.0, beta=beta, c_d=0.1, tail=tail, r_min=1.0
    )
    sched = cautious_schedule(3600.0 * np.eye(2), beta, SIGMA_S, 0.1, tail, r_min=1.0)
    assert np.all(runs.n_measurements == sched.n_measurements)
    assert np.all(runs.converged)
    d01 = runs.first_leg[0]
    assert np.allclose(runs.first_leg, d01)
    assert np.all(runs.distance <= sched.travel_bound(d01) + 1e-9)


@pytest.mark.parametrize("seed,beta,tail", [(4, 0.1, "two_sided"), (9, 0.01, "one_sided")])
def test_batched_simulation_equals_the_planner_api_run_by_run(seed, beta, tail):
    # vanderhook_sim advances a whole batch with masks; one run of it is Algorithm 1 driven
    # through CautiousPlanner (the API of the ROS planner node) with the same noise draws.
    P0 = 3600.0 * np.eye(2)
    x_true = np.array([23.0, -41.0])
    batch = simulate_localisation(
        1, np.random.default_rng(seed), beta=beta, c_d=0.1, tail=tail, r_min=1.0, x_true=[x_true]
    )
    rng = np.random.default_rng(seed)
    planner = CautiousPlanner(
        sigma_s=SIGMA_S, prior_cov=P0, beta=beta, c_d=0.1, r_min=1.0, max_measurements=60, tail=tail
    )
    mean, cov, robot, n, distance = np.zeros(2), P0, np.array([100.0, 0.0]), 0, 0.0
    while not (action := planner.next_action(mean, cov, robot, n)).done:
        distance += action.travel
        robot = action.waypoint
        d = x_true - robot
        z = math.atan2(d[1], d[0]) + SIGMA_S * rng.standard_normal(1)[0]
        upd = planner.update(mean, cov, z, robot)
        mean, cov, n = upd.mean, upd.cov, n + 1
    assert batch.n_measurements[0] == n >= 4
    assert batch.distance[0] == pytest.approx(distance, rel=1e-12)
    assert batch.final_error[0] == pytest.approx(np.linalg.norm(mean - x_true), rel=1e-9)
    assert batch.converged[0]
