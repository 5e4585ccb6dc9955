"""Modified Riccati equation (Ramdaras eq. 23) and the cost functions (Hernandez eq. 10,
Ramdaras eq. 24-26)."""

import math

import numpy as np
import pytest

from activetrack.angles import wrap_angle
from activetrack.bounds import (
    covariance_bound,
    criterion_jacobian,
    criterion_variance,
    determinant_cost,
    mre_predict,
    mre_recursion,
    mre_step,
    mre_update,
    position_determinant,
    rmse_bound,
    trace_cost,
)
from activetrack.filters import ExtendedKalmanFilter, Measurement
from activetrack.models.motion import NearlyConstantVelocityDiscrete
from activetrack.models.sensors import BearingSensor, RangeBearingSensor, RangeRateBearingSensor
from activetrack.planning.criteria import criterion_names, get_criterion

T = 1.0
MODEL = NearlyConstantVelocityDiscrete(sigma_x=2.0, sigma_y=2.0)  # Ramdaras eq. 3-4
F = MODEL.transition_matrix(T)
Q = MODEL.process_noise(T)
X0 = np.array([3000.0, -150.0, 2000.0, 100.0])
P0 = np.diag([400.0, 100.0, 400.0, 100.0])


def _spd(rng, shape=(), n=4):
    A = rng.standard_normal((*shape, n, n))
    return A @ np.swapaxes(A, -1, -2) + 0.5 * np.eye(n)


def _sensor_path(K):
    t = np.arange(K)[:, None]
    return np.hstack(
        [-500.0 + 100.0 * t, np.full((K, 1), 100.0), 300.0 + 50.0 * t, np.full((K, 1), 50.0)]
    )


# --- MRE --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "sensor",
    [
        BearingSensor(math.sqrt(2.47e-6)),  # Ramdaras s(1)
        RangeBearingSensor(31.6, math.sqrt(2.47e-6)),  # Ramdaras s(2)
        RangeRateBearingSensor(7.7, 10.0, math.radians(0.9)),  # Ramdaras s(3)
    ],
)
def test_mre_with_pd_one_equals_ekf_predicted_covariance(sensor):
    K = 8
    path = _sensor_path(K)
    ekf = ExtendedKalmanFilter(MODEL, X0, P0, t0=0.0)
    ekf.predict(T)  # P_{1|0}, x_{1|0}
    P_mre = mre_recursion(ekf.cov, F, Q, sensor, ekf.mean, path)
    for k in range(K):
        # z = h(x_{k|k-1}): zero innovation keeps the EKF mean on the MRE's nominal prediction.
        z = sensor.measure(ekf.mean, path[k])
        ekf.update([Measurement(sensor, path[k], z, ekf.time)])
        ekf.predict(ekf.time + T)
        np.testing.assert_allclose(P_mre[k], ekf.cov, rtol=1e-9, atol=1e-9)
    # The measurements matter: the final position variance is well below pure prediction.
    P_pred = ExtendedKalmanFilter(MODEL, X0, P0).cov
    for _ in range(K + 1):
        P_pred = F @ P_pred @ F.T + Q
    assert P_mre[-1][0, 0] < 0.5 * P_pred[0, 0]


def test_mre_update_equals_literal_eq23():
    rng = np.random.default_rng(5)
    P = _spd(rng, (6,)) * 50.0
    H = rng.standard_normal((6, 2, 4))
    R = np.diag([4.0, 0.25])
    pd = np.linspace(0.1, 1.0, 6)
    got = mre_step(P, F, Q, H, R, pd)
    for i in range(6):
        S = H[i] @ P[i] @ H[i].T + R
        gain_term = F @ P[i] @ H[i].T @ np.linalg.inv(S) @ H[i] @ P[i] @ F.T
        literal = F @ P[i] @ F.T - pd[i] * gain_term + Q  # Ramdaras eq. 23 as printed
        np.testing.assert_allclose(got[i], literal, rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(got, np.swapaxes(got, -1, -2))


def test_mre_lower_detection_probability_lies_above():
    rng = np.random.default_rng(6)
    P = _spd(rng) * 100.0
    x_pred = X0
    s = np.array([0.0, 0.0, 0.0, 0.0])
    results = [
        mre_predict(P, F, Q, RangeBearingSensor(31.6, 0.002, pd=pd), x_pred, s)
        for pd in (1.0, 0.7, 0.3)
    ]
    prediction = F @ P @ F.T + Q
    for hi, lo in zip([*results[1:], prediction], results, strict=True):
        eig = np.linalg.eigvalsh(hi - lo)
        assert eig.min() > -1e-9 * np.abs(eig).max()
        assert np.trace(hi) > np.trace(lo) + 1.0


def test_mre_without_detection_is_pure_prediction():
    rng = np.random.default_rng(7)
    P = _spd(rng) * 100.0
    prediction = F @ P @ F.T + Q
    np.testing.assert_allclose(mre_step(P, F, Q, np.ones((1, 4)), np.eye(1), 0.0), prediction)
    # Inside the minimum detection range (I_r = 0) the sensor contributes nothing.
    near = BearingSensor(0.01, r_min=1e5)
    np.testing.assert_allclose(mre_predict(P, F, Q, near, X0, np.zeros(4)), prediction)


def test_mre_batched_over_candidates_equals_loop():
    rng = np.random.default_rng(8)
    P = _spd(rng) * 100.0
    sensor = RangeRateBearingSensor(7.7, 10.0, math.radians(0.9), pd=0.6)
    candidates = rng.uniform(-1000.0, 1000.0, size=(3, 4, 4))
    batched = mre_predict(P, F, Q, sensor, X0, candidates)
    assert batched.shape == (3, 4, 4, 4)
    for i in range(3):
        for j in range(4):
            single = mre_predict(P, F, Q, sensor, X0, candidates[i, j])
            np.testing.assert_allclose(batched[i, j], single, rtol=1e-12)
    # The candidates really differ (the test would pass trivially otherwise).
    assert np.ptp(batched[..., 0, 0]) > 1.0


def test_mre_two_sensors_pd_one_equals_stacked_update():
    rng = np.random.default_rng(9)
    P = _spd(rng) * 100.0
    s1, s2 = BearingSensor(0.003), RangeBearingSensor(20.0, 0.01)
    states = np.array([[0.0, 0.0, 0.0, 0.0], [4000.0, 0.0, 0.0, 0.0]])
    got = mre_predict(P, F, Q, [s1, s2], X0, states)
    H = np.vstack([s1.jacobian(X0, states[0]), s2.jacobian(X0, states[1])])
    R = np.diag([0.003**2, 20.0**2, 0.01**2])
    np.testing.assert_allclose(got, mre_step(P, F, Q, H, R, 1.0), rtol=1e-9)


def test_mre_rejects_bad_inputs():
    sensor = BearingSensor(0.01)
    P = np.eye(4)
    with pytest.raises(ValueError, match="P_pred"):
        mre_predict(-P, F, Q, sensor, X0, np.zeros(4))
    with pytest.raises(ValueError, match="sensor_states"):
        mre_predict(P, F, Q, sensor, X0, np.array([np.nan, 0.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="pd"):
        mre_update(P, np.ones((1, 4)), np.eye(1), 1.5)
    with pytest.raises(ValueError, match="H"):
        mre_update(P, np.ones((2, 4)), np.eye(1), 1.0)


# --- costs ------------------------------------------------------------------------------------


def test_rmse_bound_is_hernandez_eq10():
    P = np.diag([4.0, 1.0, 9.0, 1.0])
    assert rmse_bound(P) == 3.0
    batch = np.stack([P, np.diag([16.0, 0.0, 1.0, 0.0])])
    np.testing.assert_array_equal(rmse_bound(batch), [3.0, 4.0])
    # From a Fisher information: b_k = max(sqrt(J^-1(1,1)), sqrt(J^-1(3,3))).
    J = np.diag([1 / 25.0, 1.0, 1 / 4.0, 1.0])
    assert rmse_bound(covariance_bound(J)) == pytest.approx(5.0, rel=1e-12)


def test_trace_determinant_and_position_determinant():
    P = np.array(
        [[4.0, 0.5, 1.0, 0.0], [0.5, 2.0, 0.0, 0.0], [1.0, 0.0, 9.0, 0.3], [0.0, 0.0, 0.3, 1.0]]
    )
    assert trace_cost(P) == 16.0
    assert determinant_cost(P) == pytest.approx(np.linalg.det(P), rel=1e-12)
    assert position_determinant(P) == pytest.approx(4.0 * 9.0 - 1.0, rel=1e-12)  # eq. 24
    assert position_determinant(np.stack([P, 2 * P])).tolist() == pytest.approx([35.0, 140.0])


def _criteria_functions(sensor):
    def rel(x):
        return x - sensor

    return {
        "heading": lambda x: math.atan2(x[3], x[1]),
        "range": lambda x: math.hypot(rel(x)[0], rel(x)[2]),
        "doppler": lambda x: (
            (rel(x)[0] * rel(x)[1] + rel(x)[2] * rel(x)[3]) / math.hypot(rel(x)[0], rel(x)[2])
        ),
        "bearing": lambda x: math.atan2(rel(x)[2], rel(x)[0]),
    }


@pytest.mark.parametrize("criterion", ["heading", "range", "doppler", "bearing"])
def test_criterion_jacobians_match_central_differences(criterion):
    x = np.array([30.0, 2.0, -40.0, -3.0])
    sensor = np.array([5.0, 1.0, 10.0, 0.5])
    f = _criteria_functions(sensor)[criterion]
    h = 1e-6
    numeric = np.array([wrap_angle(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(4)])
    np.testing.assert_allclose(criterion_jacobian(criterion, x, sensor), numeric, atol=1e-8)


def test_doppler_row_matches_ramdaras_eq26_for_a_still_sensor():
    x, xd, y, yd = 300.0, -20.0, 400.0, 15.0
    r = 500.0
    eq26 = [
        xd / r - (x * x * xd + x * y * yd) / r**3,
        x / r,
        yd / r - (x * y * xd + y * y * yd) / r**3,
        y / r,
    ]
    np.testing.assert_allclose(criterion_jacobian("doppler", np.array([x, xd, y, yd])), eq26)


def test_criterion_variance_values():
    # Isotropic position variance s2: range variance s2, bearing variance s2 / r^2 (eq. 25).
    s2 = 4.0
    P = np.diag([s2, 1.0, s2, 1.0])
    x = np.array([300.0, 0.0, 400.0, 10.0])
    assert criterion_variance("range", P, x) == pytest.approx(s2)
    assert criterion_variance("bearing", P, x) == pytest.approx(s2 / 500.0**2)
    # Heading along +y at 10 m/s: the cross-track velocity variance 1 over v^2.
    assert criterion_variance("heading", P, x) == pytest.approx(1.0 / 100.0)
    batch = np.stack([P, 2 * P, 3 * P])
    range_criterion = get_criterion("range")
    np.testing.assert_allclose(range_criterion.of_covariance(batch, x), [s2, 2 * s2, 3 * s2])


def test_criterion_registry_names_and_errors():
    P = np.diag([4.0, 1.0, 9.0, 1.0])
    x = np.array([300.0, 1.0, 400.0, 1.0])
    assert get_criterion("b_k").of_covariance(P) == 3.0  # Hernandez eq. 10
    assert get_criterion("det_pos").of_covariance(P) == 36.0  # Ramdaras eq. 24
    assert get_criterion("trace").of_information(np.linalg.inv(P)) == pytest.approx(15.0)
    # GOSPA's localisation (p = 2) of a held track: E|e|^2 = P(1,1) + P(3,3)
    assert get_criterion("trace_pos").of_covariance(P) == 13.0
    assert get_criterion("trace_pos").of_information(np.linalg.inv(P)) == pytest.approx(13.0)
    with pytest.raises(ValueError, match="singular"):
        get_criterion("trace_pos").of_information(np.zeros((4, 4)))
    assert criterion_names() == (
        "b_k", "trace", "trace_pos", "det_pos", "heading", "range", "doppler", "bearing"
    )  # fmt: skip
    assert criterion_names("pcrlb") == ("b_k", "trace", "trace_pos", "det_pos")
    assert criterion_names("selection") == ("det_pos", "heading", "range", "doppler", "bearing")
    # One vocabulary: the old aliases are gone.
    for old in ("rmse_bound", "position_determinant", "determinant", "nope"):
        with pytest.raises(ValueError, match="criterion must be one of"):
            get_criterion(old)
    with pytest.raises(ValueError, match="for PCRLB planning"):
        get_criterion("heading", "pcrlb")
    with pytest.raises(ValueError, match="x"):
        get_criterion("bearing").of_covariance(P)
    assert get_criterion("bearing").of_covariance(P, x) == pytest.approx(
        criterion_variance("bearing", P, x)
    )
    with pytest.raises(ValueError, match="x"):
        criterion_jacobian("heading", np.array([1.0, 0.0, 2.0, 0.0]))
    with pytest.raises(ValueError, match="x"):
        criterion_jacobian("range", x, sensor_state=x)
    with pytest.raises(ValueError, match="criterion"):
        criterion_jacobian("speed", x)
    with pytest.raises(ValueError, match="P"):
        trace_cost(np.ones((2, 3)))


def test_a_sure_look_mixed_with_each_factor_is_after_look_bit_for_bit():
    """TargetPrediction.after_sure_look (the Joseph update computed once per sensor and track,
    as footprint pointing scores several beam centres) gives after_look's bits for every
    detection factor, out of range (no update) too."""
    from activetrack.planning.selection import TargetPrediction

    F, Q = MODEL.transition_matrix(1.0), MODEL.process_noise(1.0)
    p = TargetPrediction.from_posterior(
        [1000.0, 5.0, 2000.0, -3.0], np.diag([400.0, 4.0, 400.0, 4.0]), F, Q
    )
    sensor = RangeBearingSensor(sigma_r=30.0, sigma_b=0.01, pd=0.85, r_max=3000.0)
    for pv in ([0.0, 0.0, 0.0, 0.0], [-5000.0, 0.0, 0.0, 0.0]):  # in range, out of range
        pv = np.array(pv)
        look = p.sure_look(sensor, pv)
        assert look[1] == float(sensor.in_range(p.x, pv))
        for factor in (0.0, 0.3, 0.85, 1.0):
            np.testing.assert_array_equal(
                p.after_sure_look(look, factor).P, p.after_look(sensor, pv, factor).P
            )
    assert not np.array_equal(p.after_look(sensor, np.zeros(4), 0.85).P, p.P)
