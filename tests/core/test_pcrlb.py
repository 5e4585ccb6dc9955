"""PCRLB for linear dynamics (Hernandez eq. 3, 8-9): exactness, closed form, batching, inputs."""

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from activetrack.bounds import (
    covariance_bound,
    gaussian_samples,
    measurement_information,
    pcrlb_step,
    pcrlb_trajectory,
    propagate_samples,
)
from activetrack.models.base import GaussianSensor
from activetrack.models.motion import NearlyConstantVelocity
from activetrack.models.sensors import (
    AmbiguousBearingSensor,
    BearingSensor,
    RangeBearingSensor,
    RangeRateBearingSensor,
)

H_POS = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])


@dataclass(frozen=True)
class LinearPositionSensor(GaussianSensor):
    """z = (x_t - x_s, y_t - y_s) + v: a linear sensor with the sensor interface."""

    sigma_x: float
    sigma_y: float
    pd: float = 1.0
    r_min: float = 0.0
    r_max: float = math.inf

    kind: ClassVar[str] = "position"
    components: ClassVar[tuple[str, ...]] = ("x", "y")
    dim_z: ClassVar[int] = 2

    @property
    def R(self):
        return np.diag([self.sigma_x**2, self.sigma_y**2])

    def measure(self, target_pv, sensor_pv):
        d = np.asarray(target_pv, float) - np.asarray(sensor_pv, float)
        return d[..., [0, 2]]

    def jacobian(self, target_pv, sensor_pv):
        d = np.asarray(target_pv, float) - np.asarray(sensor_pv, float)
        return np.broadcast_to(H_POS, (*d.shape[:-1], 2, 4)).copy()

    def residual(self, z, zhat):
        return np.asarray(z, float) - np.asarray(zhat, float)

    def in_range(self, target_pv, sensor_pv):
        d = np.asarray(target_pv, float) - np.asarray(sensor_pv, float)
        r = np.hypot(d[..., 0], d[..., 2])
        return (r >= self.r_min) & (r <= self.r_max)


DT = 5.0
MODEL = NearlyConstantVelocity(q=0.05)
F = MODEL.transition_matrix(DT)
Q = MODEL.process_noise(DT)
X0 = np.array([1000.0, -4.0, 1000.0, -4.0])  # Hernandez sec. 5.1 prior mean
C0 = np.diag([10.0, 1.0, 10.0, 1.0])  # Hernandez sec. 5.1 prior covariance


def _samples(n=400, seed=1):
    return gaussian_samples(X0, C0, n, np.random.default_rng(seed))


def _candidates(shape=(3, 3)):
    """Sensor pv states on a grid around (1800, 2000), shape (*shape, 4)."""
    gx, gy = np.meshgrid(np.linspace(-300, 300, shape[0]), np.linspace(-200, 200, shape[1]))
    pv = np.zeros((*gx.shape, 4))
    pv[..., 0], pv[..., 1] = 1800.0 + gx, -40.0
    pv[..., 2], pv[..., 3] = 2000.0 + gy, -40.0
    return pv


# --- linear-Gaussian exactness ----------------------------------------------------------------


def test_pcrlb_equals_kalman_covariance_for_linear_gaussian_problem():
    sensor = LinearPositionSensor(3.0, 5.0)
    K = 12
    paths = np.tile(np.array([0.0, 0.0, 0.0, 0.0]), (K, 1))  # (K, 4), one sensor
    J = pcrlb_trajectory(np.linalg.inv(C0), F, Q, _samples(50), sensor, paths, rng=None)

    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x, kf.P, kf.F, kf.Q, kf.H, kf.R = X0.copy(), C0.copy(), F, Q, H_POS, sensor.R
    for k in range(K):
        kf.predict()
        kf.update(kf.H @ kf.x)  # the covariance does not depend on z
        np.testing.assert_allclose(covariance_bound(J[k]), kf.P, rtol=1e-9, atol=1e-12)
    # Steady state reached: a real, non-trivial number (position variance below R_xx = 9).
    assert 0.5 < kf.P[0, 0] < 9.0


def test_pcrlb_two_linear_sensors_add_information():
    s1, s2 = LinearPositionSensor(3.0, 5.0), LinearPositionSensor(4.0, 2.0)
    X = _samples(20)
    J_Z = measurement_information([s1, s2], np.zeros((2, 4)), X)
    expected = H_POS.T @ (np.linalg.inv(s1.R) + np.linalg.inv(s2.R)) @ H_POS
    np.testing.assert_allclose(J_Z, expected, rtol=1e-12)


# --- closed-form bearing information -----------------------------------------------------------


def test_bearing_information_closed_form_value():
    # One sample at dx = 3, dy = 4 (r^2 = 25): H = (-4, 0, 3, 0)/25 (eq. 9), sigma = 0.1.
    X = np.array([[3.0, 0.0, 4.0, 0.0]])
    J_Z = measurement_information(BearingSensor(0.1), np.zeros(4), X)
    expected = np.zeros((4, 4))
    expected[0, 0], expected[2, 2] = 16 / 625 / 0.01, 9 / 625 / 0.01
    expected[0, 2] = expected[2, 0] = -12 / 625 / 0.01
    np.testing.assert_allclose(J_Z, expected, rtol=1e-13)


@pytest.mark.parametrize("cls", [BearingSensor, AmbiguousBearingSensor])
def test_closed_form_bearing_equals_generic_jacobian_path(cls):
    X = _samples(300)
    sensors = [cls(0.01, pd=0.7, r_min=1280.0), cls(0.02, r_min=0.0, r_max=1400.0)]
    states = np.stack([_candidates((4, 3)), _candidates((4, 3)) - [300, 0, 600, 0]], axis=-2)
    fast = measurement_information(sensors, states, X, method="auto")
    generic = measurement_information(sensors, states, X, method="jacobian")
    assert fast.shape == (3, 4, 4, 4)
    # Both r_min and r_max cut some samples (otherwise this would not test I_r agreement).
    r = np.hypot(X[:, 0] - states[..., 0, 0, None], X[:, 2] - states[..., 0, 2, None])
    assert 0 < np.mean(r < 1280.0) < 1
    np.testing.assert_allclose(fast, generic, rtol=1e-11, atol=1e-14 * np.abs(fast).max())
    # With a model-state chain rule (identity here) both paths agree as well.
    K = np.broadcast_to(np.eye(4), (X.shape[0], 4, 4))
    chained = measurement_information(sensors, states, X, kinematics_jacobian=K)
    np.testing.assert_allclose(chained, fast, rtol=1e-11, atol=1e-14 * np.abs(fast).max())


def test_range_bearing_information_matches_hand_formula():
    # Range row (dx, 0, dy, 0)/r, bearing row (-dy, 0, dx, 0)/r^2, R = diag(sr^2, sb^2).
    sensor = RangeBearingSensor(sigma_r=2.0, sigma_b=0.05)
    X = np.array([[3.0, 1.0, 4.0, -1.0], [-6.0, 0.0, 8.0, 2.0]])
    J_Z = measurement_information(sensor, np.zeros(4), X)
    expected = np.zeros((4, 4))
    for dx, dy in X[:, [0, 2]]:
        r2 = dx * dx + dy * dy
        hr = np.array([dx, 0, dy, 0]) / np.sqrt(r2)
        hb = np.array([-dy, 0, dx, 0]) / r2
        expected += (np.outer(hr, hr) / 4.0 + np.outer(hb, hb) / 0.0025) / 2
    np.testing.assert_allclose(J_Z, expected, rtol=1e-12)


# --- I_r and pd ------------------------------------------------------------------------------


def test_minimum_detection_range_zeroes_information():
    X = _samples(200)
    state = np.array([1000.0, 0.0, 1000.0, 0.0])  # inside the sample cloud
    inside_all = BearingSensor(0.01, r_min=1e4)
    assert np.all(measurement_information(inside_all, state, X) == 0.0)
    assert np.all(measurement_information(inside_all, state, X, method="jacobian") == 0.0)
    # A partial cut equals the information of the far samples only, still divided by M.
    r_min = 4.0
    r = np.hypot(X[:, 0] - state[0], X[:, 2] - state[2])
    far = r >= r_min
    assert 0.2 < far.mean() < 0.9
    cut = measurement_information(BearingSensor(0.01, r_min=r_min), state, X)
    full_far = measurement_information(BearingSensor(0.01), state, X[far])
    np.testing.assert_allclose(cut, full_far * far.mean(), rtol=1e-12)


@pytest.mark.parametrize(
    "make",
    [
        lambda pd: BearingSensor(0.01, pd=pd),
        lambda pd: RangeRateBearingSensor(5.0, 1.0, 0.01, pd=pd),
        lambda pd: LinearPositionSensor(3.0, 4.0, pd=pd),
    ],
)
def test_detection_probability_scales_information(make):
    X = _samples(100)
    states = _candidates((2, 2))
    full = measurement_information(make(1.0), states, X)
    part = measurement_information(make(0.35), states, X)
    np.testing.assert_allclose(part, 0.35 * full, rtol=1e-12)
    assert np.abs(full).max() > 0


# --- eq. 3 step and batching -------------------------------------------------------------------


def test_pcrlb_step_matches_direct_formula():
    rng = np.random.default_rng(3)
    A = rng.standard_normal((5, 4, 4))
    J_prev = A @ np.swapaxes(A, -1, -2) + 0.5 * np.eye(4)
    J_Z = measurement_information(
        BearingSensor(0.02), _candidates((5, 1)).reshape(5, 4), _samples()
    )
    J = pcrlb_step(J_prev, F, Q, J_Z)
    direct = np.linalg.inv(Q + F @ np.linalg.inv(J_prev) @ F.T) + J_Z
    np.testing.assert_allclose(J, direct, rtol=1e-9)
    np.testing.assert_array_equal(J, np.swapaxes(J, -1, -2))


def test_batched_trajectory_equals_per_candidate_loop():
    sensors = [BearingSensor(0.01, r_min=100.0), RangeBearingSensor(20.0, 0.02, pd=0.8)]
    K = 4
    rng = np.random.default_rng(7)
    samples = propagate_samples(_samples(300), F, Q, K, rng)
    base = np.array([[1800.0, -40.0, 2000.0, -40.0], [1500.0, 0.0, 400.0, 10.0]])
    offsets = rng.normal(0.0, 200.0, size=(K, 2, 3, 2, 4))
    paths = base + offsets  # (K, 2, 3, S=2, 4): a 2 x 3 batch of candidate paths
    J0 = np.linalg.inv(C0)
    J = pcrlb_trajectory(J0, F, Q, samples, sensors, paths)
    assert J.shape == (K, 2, 3, 4, 4)
    for a in range(2):
        for b in range(3):
            J_loop = J0
            for k in range(K):
                J_Z = measurement_information(sensors, paths[k, a, b], samples[k])
                J_loop = pcrlb_step(J_loop, F, Q, J_Z)
                np.testing.assert_allclose(J[k, a, b], J_loop, rtol=1e-12)
    # Information only grows with sensors compared with the prior-only recursion.
    J_prior = J0
    for _ in range(K):
        J_prior = pcrlb_step(J_prior, F, Q, np.zeros((4, 4)))
    assert np.all(np.linalg.eigvalsh(J[-1] - J_prior) > -1e-9)
    assert np.trace(J[-1, 0, 0] - J_prior) > 0.2


def test_trajectory_counts_only_the_active_sensors_of_each_epoch():
    sensors = [BearingSensor(0.01), RangeBearingSensor(20.0, 0.02)]
    K = 3
    samples = propagate_samples(_samples(300), F, Q, K, np.random.default_rng(3))
    paths = np.broadcast_to(
        np.array([[1800.0, -40.0, 2000.0, -40.0], [1500.0, 0.0, 400.0, 10.0]]), (K, 2, 4)
    )
    J0 = np.linalg.inv(C0)
    active = np.array([[True, True], [False, True], [False, False]])
    J = pcrlb_trajectory(J0, F, Q, samples, sensors, paths, active=active)
    np.testing.assert_array_equal(
        pcrlb_trajectory(J0, F, Q, samples, sensors, paths, active=np.ones((K, 2), bool)),
        pcrlb_trajectory(J0, F, Q, samples, sensors, paths),
    )
    J1 = pcrlb_step(J0, F, Q, measurement_information(sensors, paths[0], samples[0]))
    J2 = pcrlb_step(J1, F, Q, measurement_information(sensors[1], paths[1, 1], samples[1]))
    J3 = pcrlb_step(J2, F, Q, np.zeros((4, 4)))  # nobody looked: prediction only
    np.testing.assert_allclose(J, np.stack([J1, J2, J3]), rtol=1e-12)
    with pytest.raises(ValueError, match="active must be"):
        pcrlb_trajectory(J0, F, Q, samples, sensors, paths, active=active[:2])


def test_trajectory_with_rng_propagates_prior_like_propagate_samples():
    sensor = BearingSensor(0.01)
    paths = np.tile([1800.0, -40.0, 2000.0, -40.0], (3, 1))
    X = _samples(200)
    J_a = pcrlb_trajectory(np.linalg.inv(C0), F, Q, X, sensor, paths, np.random.default_rng(5))
    samples = propagate_samples(X, F, Q, 3, np.random.default_rng(5))
    J_b = pcrlb_trajectory(np.linalg.inv(C0), F, Q, samples, sensor, paths)
    np.testing.assert_allclose(J_a, J_b, rtol=1e-12)


def test_propagate_samples_moments():
    X = gaussian_samples(X0, C0, 40000, np.random.default_rng(11))
    out = propagate_samples(X, F, Q, 3, np.random.default_rng(12))
    F3 = np.linalg.matrix_power(F, 3)
    cov3 = F3 @ C0 @ F3.T + sum(
        np.linalg.matrix_power(F, i) @ Q @ np.linalg.matrix_power(F, i).T for i in range(3)
    )
    standard_error = np.sqrt(np.diag(cov3) / X.shape[0])
    assert np.all(np.abs(out[2].mean(axis=0) - F3 @ X0) < 4 * standard_error)
    np.testing.assert_allclose(np.cov(out[2].T), cov3, rtol=0.05, atol=0.05 * cov3.max())
    # Noise-free propagation is exactly F^k X.
    np.testing.assert_allclose(propagate_samples(X[:5], F, Q, 3)[2], X[:5] @ F3.T, rtol=1e-13)


def test_covariance_bound_is_inverse():
    rng = np.random.default_rng(2)
    A = rng.standard_normal((3, 4, 4))
    J = A @ np.swapaxes(A, -1, -2) + np.eye(4)
    np.testing.assert_allclose(
        covariance_bound(J) @ J, np.broadcast_to(np.eye(4), J.shape), atol=1e-10
    )


# --- bad inputs ------------------------------------------------------------------------------


def test_bad_inputs_raise_value_error_naming_argument():
    X = _samples(10)
    sensor = BearingSensor(0.01)
    paths = np.tile([1800.0, -40.0, 2000.0, -40.0], (2, 1))
    with pytest.raises(ValueError, match="J0"):
        pcrlb_trajectory(np.diag([1.0, -1.0, 1.0, 1.0]), F, Q, X, sensor, paths)
    with pytest.raises(ValueError, match="J0"):
        pcrlb_trajectory(np.diag([1.0, np.nan, 1.0, 1.0]), F, Q, X, sensor, paths)
    bad_paths = paths.copy()
    bad_paths[1, 2] = np.inf
    with pytest.raises(ValueError, match="sensor_paths"):
        pcrlb_trajectory(np.linalg.inv(C0), F, Q, X, sensor, bad_paths)
    with pytest.raises(ValueError, match="sensor_states"):
        measurement_information(sensor, np.array([np.nan, 0, 0, 0]), X)
    with pytest.raises(ValueError, match="sensor_states"):
        measurement_information([sensor, sensor], np.zeros((3, 4)), X)
    with pytest.raises(ValueError, match="target_samples"):
        measurement_information(sensor, np.zeros(4), np.zeros((0, 4)))
    with pytest.raises(ValueError, match="J_prev"):
        pcrlb_step(np.array([[1.0, 2.0], [0.0, 1.0]]), np.eye(2), np.eye(2), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="zero range"):
        measurement_information(sensor, X[3], X)
    with pytest.raises(ValueError, match="method"):
        measurement_information(RangeBearingSensor(1.0, 0.1), np.zeros(4), X, method="closed_form")
    with pytest.raises(ValueError, match="n_samples"):
        gaussian_samples(X0, C0, 0, np.random.default_rng(0))
