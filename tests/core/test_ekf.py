"""Tests of the EKF (activetrack.filters.ekf) and the shared filter interface."""

import math

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter as FilterpyEKF
from linear_sensor import LinearPositionSensor

from activetrack.filters import (
    ExtendedKalmanFilter,
    Measurement,
    ParticleFilter,
    UpdateInfo,
    make_filter,
)
from activetrack.filters.jpda import pda_residuals
from activetrack.models.base import GaussianSensor
from activetrack.models.motion import (
    CircularMotion,
    CircularMotionKnownOmega,
    ConstantTurn,
    NearlyConstantVelocity,
    NearlyConstantVelocityDiscrete,
)
from activetrack.models.sensors import (
    AmbiguousBearingSensor,
    BearingSensor,
    RangeBearingSensor,
    RangeRateBearingSensor,
)
from activetrack.scenarios.schema import TrackerConfig


# The built-in sensors with GaussianSensor's generic members instead of their inline formulas
# (a plain subclass keeps the inline ones).
class GenericBearing(BearingSensor):
    linearize = GaussianSensor.linearize
    log_likelihood = GaussianSensor.log_likelihood
    log_miss_likelihood = GaussianSensor.log_miss_likelihood


class GenericRangeBearing(RangeBearingSensor):
    linearize = GaussianSensor.linearize
    log_likelihood = GaussianSensor.log_likelihood
    log_miss_likelihood = GaussianSensor.log_miss_likelihood


T = 5.0
X0 = np.array([3000.0, -4.0, 2000.0, 3.0])
P0 = np.diag([200.0**2, 2.0**2, 200.0**2, 2.0**2])
SENSOR_A = np.array([0.0, 2.0, 0.0, 1.0])
SENSOR_B = np.array([1000.0, 0.0, -500.0, 0.0])


def simulate(model, x0, sensors, n_steps, rng, dt=T):
    """Truth and per-step measurement lists for (sensor, sensor_pv) pairs (sensors still)."""
    x = x0.copy()
    steps = []
    for k in range(1, n_steps + 1):
        x = model.sample(x, dt, rng)
        pv = model.kinematics(x)
        ms = [
            Measurement(sensor, s, sensor.sample(pv, s, rng), k * dt, sensor_id=f"s{j}")
            for j, (sensor, s) in enumerate(sensors)
        ]
        steps.append((k * dt, x.copy(), ms))
    return steps


def test_matches_filterpy_range_bearing_and_bearing_two_sensors():
    model = NearlyConstantVelocity(q=0.05)
    rb = RangeBearingSensor(sigma_r=10.0, sigma_b=0.01)
    b = BearingSensor(sigma=0.02)
    steps = simulate(model, X0, [(rb, SENSOR_A), (b, SENSOR_B)], 20, np.random.default_rng(1))

    ekf = ExtendedKalmanFilter(model, X0, P0)
    fp = FilterpyEKF(dim_x=4, dim_z=2)
    fp.x, fp.P = X0.copy(), P0.copy()
    fp.F, fp.Q = model.transition_matrix(T), model.process_noise(T)
    for t, _, ms in steps:
        info = ekf.step(t, ms)
        fp.predict()
        log_lik = 0.0
        for m in ms:
            fp.update(
                m.z,
                HJacobian=m.sensor.jacobian,
                Hx=m.sensor.measure,
                R=m.sensor.R,
                args=(m.sensor_state,),
                hx_args=(m.sensor_state,),
                residual=m.sensor.residual,
            )
            log_lik += fp.log_likelihood
        np.testing.assert_allclose(ekf.mean, fp.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ekf.cov, fp.P, rtol=0, atol=1e-9)
        assert info.log_likelihood == pytest.approx(log_lik, abs=1e-9)
        assert info.nis == pytest.approx(sum(info.nis_per_measurement), abs=1e-12)
        assert info.dof == 3 and info.n_detections == 2 and info.sensor_ids == ("s0", "s1")
    # The run is informative: the covariance shrank by orders of magnitude from P0.
    assert ekf.cov[0, 0] < 0.01 * P0[0, 0]


def test_matches_filterpy_nonlinear_circular_motion():
    """Nonlinear model: filterpy with predict_x = model.propagate and F = model.jacobian."""
    model = CircularMotion(sigma_omega=0.002, sigma_v=0.05)
    x0 = np.array([0.3, 500.0, 800.0, 0.02, 2.0])
    P = np.diag([0.05**2, 20.0**2, 20.0**2, 0.005**2, 0.3**2])
    sensor = RangeBearingSensor(sigma_r=2.0, sigma_b=0.005)

    class ModelEKF(FilterpyEKF):
        def predict_x(self, u=0):
            self.x = model.propagate(self.x, 1.0)

    steps = simulate(model, x0, [(sensor, SENSOR_A)], 30, np.random.default_rng(2), dt=1.0)
    ekf = ExtendedKalmanFilter(model, x0, P)
    fp = ModelEKF(dim_x=5, dim_z=2)
    fp.x, fp.P, fp.Q = x0.copy(), P.copy(), model.process_noise(1.0)
    s = SENSOR_A
    for t, _, ms in steps:
        ekf.step(t, ms)
        fp.F = model.jacobian(fp.x, 1.0)  # linearise at the prior state, as ekf.predict does
        fp.predict()
        fp.update(
            ms[0].z,
            HJacobian=lambda x: (
                sensor.jacobian(model.kinematics(x), s) @ model.kinematics_jacobian(x)
            ),
            Hx=lambda x: sensor.measure(model.kinematics(x), s),
            R=sensor.R,
            residual=sensor.residual,
        )
        np.testing.assert_allclose(ekf.mean, fp.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ekf.cov, fp.P, rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    ("fast", "generic"),
    [
        (BearingSensor(0.01), GenericBearing(0.01)),
        (RangeBearingSensor(5.0, 0.01), GenericRangeBearing(5.0, 0.01)),
    ],
)
def test_inline_sensor_formulas_equal_generic_path_across_wrap(fast, generic):
    """Sensor west of the target: bearings straddle +-pi, so the residual must wrap."""
    model = NearlyConstantVelocity(q=0.01)
    x0 = np.array([-1000.0, 1.0, 5.0, -0.6])  # bearing from the origin ~ +pi, y crosses 0
    P = np.diag([50.0**2, 1.0, 30.0**2, 1.0])
    steps = simulate(model, x0, [(fast, np.zeros(4))], 15, np.random.default_rng(3))
    a, b = ExtendedKalmanFilter(model, x0, P), ExtendedKalmanFilter(model, x0, P)
    signs = set()
    for t, _, ms in steps:
        signs.add(float(np.sign(ms[0].z[-1])))
        ia = a.step(t, ms)
        ib = b.step(t, [Measurement(generic, m.sensor_state, m.z, m.time) for m in ms])
        np.testing.assert_allclose(a.mean, b.mean, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.cov, b.cov, rtol=1e-12, atol=1e-12)
        assert ia.nis == pytest.approx(ib.nis, rel=1e-12)
        assert ia.nis < 30.0  # an unwrapped residual of ~2 pi would give NIS ~ 4e5
    assert signs == {-1.0, 1.0}  # the measured bearings really crossed the +-pi cut


def hand_written_kalman(F, Q, H, R, x, P, zs):
    """Textbook linear KF, standard (non-Joseph) covariance form, for comparison."""
    out = []
    for z in zs:
        x = F @ x
        P = F @ P @ F.T + Q
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        x = x + K @ (z - H @ x)
        P = (np.eye(len(x)) - K @ H) @ P
        out.append((x, P))
    return out


@pytest.mark.parametrize("model", [NearlyConstantVelocity(0.3), ConstantTurn(0.05, 0.3)])
def test_equals_linear_kalman_filter_on_linear_model(model):
    sensor = LinearPositionSensor(sigma=15.0)
    s = np.array([100.0, 0.0, -200.0, 0.0])
    steps = simulate(model, X0, [(sensor, s)], 25, np.random.default_rng(4))
    F, Q = model.transition_matrix(T), model.process_noise(T)
    reference = hand_written_kalman(
        F, Q, sensor.H, sensor.R, X0, P0, [ms[0].z + sensor.H @ s for _, _, ms in steps]
    )
    ekf = ExtendedKalmanFilter(model, X0, P0)
    for (t, _, ms), (x_ref, P_ref) in zip(steps, reference, strict=True):
        ekf.step(t, ms)
        np.testing.assert_allclose(ekf.mean, x_ref, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ekf.cov, P_ref, rtol=1e-9, atol=1e-9)


def test_sequential_update_equals_stacked_for_linear_sensors():
    """Two linear sensors in one step: sequential = one stacked update with blkdiag(R1, R2)."""
    model = NearlyConstantVelocity(0.3)
    s1, s2 = LinearPositionSensor(10.0), LinearPositionSensor(25.0)
    z1, z2 = np.array([2990.0, 2030.0]), np.array([3010.0, 1990.0])
    ekf = ExtendedKalmanFilter(model, X0, P0)
    info = ekf.step(T, [Measurement(s1, np.zeros(4), z1, T), Measurement(s2, np.zeros(4), z2, T)])
    F, Q = model.transition_matrix(T), model.process_noise(T)
    x, P = F @ X0, F @ P0 @ F.T + Q
    H = np.vstack([s1.H, s2.H])
    R = np.diag([100.0, 100.0, 625.0, 625.0])
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    nu = np.concatenate([z1, z2]) - H @ x
    np.testing.assert_allclose(ekf.mean, x + K @ nu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ekf.cov, (np.eye(4) - K @ H) @ P, rtol=1e-9, atol=1e-9)
    # The sequential NIS sum equals the stacked NIS (independent sequential innovations).
    assert info.nis == pytest.approx(nu @ np.linalg.solve(S, nu), rel=1e-9)
    assert info.dof == 4


def test_missed_detections_leave_the_prediction():
    model = NearlyConstantVelocity(0.1)
    sensor = BearingSensor(0.01, pd=0.6)
    ekf = ExtendedKalmanFilter(model, X0, P0)
    reference = ExtendedKalmanFilter(model, X0, P0)
    missed = [Measurement(sensor, SENSOR_A, None, T, "a"), Measurement(sensor, SENSOR_B, None, T)]
    info = ekf.step(T, missed)
    reference.predict(T)
    np.testing.assert_array_equal(ekf.mean, reference.mean)
    np.testing.assert_array_equal(ekf.cov, reference.cov)
    assert (info.n_detections, info.n_missed, info.dof) == (0, 2, 0)
    assert math.isnan(info.nis) and info.log_likelihood == 0.0
    # A detection mixed with misses gives exactly the single-detection update.
    z = np.array([math.atan2(2000.0, 3000.0) + 0.01])
    hit = Measurement(sensor, SENSOR_A, z, 2 * T)
    only_hit = reference.step(2 * T, [hit])
    mixed = ekf.step(2 * T, [Measurement(sensor, SENSOR_B, None, 2 * T), hit])
    np.testing.assert_array_equal(ekf.mean, reference.mean)
    np.testing.assert_array_equal(ekf.cov, reference.cov)
    assert mixed.nis == only_hit.nis and mixed.n_missed == 1
    assert math.isnan(mixed.nis_per_measurement[0])


def test_covariance_stays_symmetric_positive_definite_bearing_only():
    """200 bearing-only steps from a moving platform, near and far, precise sensor."""
    model = NearlyConstantVelocity(1e-4)
    sensor = BearingSensor(0.001)
    rng = np.random.default_rng(5)
    x = X0.copy()
    ekf = ExtendedKalmanFilter(model, X0 + np.array([300.0, 1.0, -300.0, -1.0]), P0)
    min_eig = []
    for k in range(1, 201):
        t = k * 1.0
        x = model.sample(x, 1.0, rng)
        s = np.array(
            [2500.0 + 600.0 * math.cos(0.05 * t), 0, 1500.0 + 600.0 * math.sin(0.05 * t), 0]
        )
        ekf.step(t, [Measurement(sensor, s, sensor.sample(x, s, rng), t)])
        P = ekf.cov
        np.testing.assert_array_equal(P, P.T)
        min_eig.append(np.linalg.eigvalsh(P)[0])
    assert min(min_eig) > 0.0
    # And it converged: position error within 4 sigma of the final covariance.
    err = ekf.mean - x
    assert abs(err[0]) < 4 * math.sqrt(ekf.cov[0, 0]) and abs(err[2]) < 4 * math.sqrt(ekf.cov[2, 2])


def nis_mean(model, sensors, filter_sensors, n_runs, n_steps, seed):
    rng = np.random.default_rng(seed)
    L0 = np.linalg.cholesky(P0)
    total, count = 0.0, 0
    for _ in range(n_runs):
        x0 = X0 + L0 @ rng.standard_normal(4)
        steps = simulate(model, x0, sensors, n_steps, rng)
        ekf = ExtendedKalmanFilter(model, X0, P0)
        for t, _, ms in steps:
            ms = [
                Measurement(fs, m.sensor_state, m.z, m.time)
                for fs, m in zip(filter_sensors, ms, strict=True)
            ]
            info = ekf.step(t, ms)
            total += info.nis
            count += info.dof
    return total / count  # mean NIS per measurement dimension: 1 for a consistent filter


def test_nis_has_chi_square_mean():
    """E[NIS] = dim_z. Averaging n independent chi-square(d) draws (the innovations of a
    consistent filter are white), the mean NIS per dimension has std sqrt(2 / (n d)); with
    150 runs x 10 steps x d = 2 that is 0.026, so the band 0.1 is ~4 sigma.
    """
    model = NearlyConstantVelocity(0.05)
    linear = [(LinearPositionSensor(20.0), SENSOR_A)]
    per_dim = nis_mean(model, linear, [linear[0][0]], 150, 10, seed=6)
    assert per_dim == pytest.approx(1.0, abs=0.1)
    # Range-bearing at ~3.6 km with a 200 m prior: the second-order terms (~ 5 m in range,
    # 0.002 rad in bearing) are small against sigma_r = 30 m, sigma_b = 0.01 rad: same band.
    rb = RangeBearingSensor(sigma_r=30.0, sigma_b=0.01)
    per_dim = nis_mean(model, [(rb, SENSOR_A)], [rb], 150, 10, seed=7)
    assert per_dim == pytest.approx(1.0, abs=0.1)
    # The test can fail: a filter that assumes half the true noise sees NIS ~ 4 per dim.
    optimistic = RangeBearingSensor(sigma_r=15.0, sigma_b=0.005)
    per_dim = nis_mean(model, [(rb, SENSOR_A)], [optimistic], 50, 10, seed=8)
    assert per_dim > 2.5


@pytest.mark.parametrize(
    ("model", "x0", "P"),
    [
        (NearlyConstantVelocityDiscrete(0.05, 0.05), X0, P0),
        (ConstantTurn(0.01, 0.05), X0, P0),
        (
            CircularMotion(0.001, 0.05),
            np.array([0.5, 3000.0, 2000.0, 0.01, 3.0]),
            np.diag([0.1, 100.0**2, 100.0**2, 0.005**2, 0.5**2]),
        ),
        (
            CircularMotionKnownOmega(0.01, 0.05),
            np.array([0.5, 3000.0, 2000.0, 3.0]),
            np.diag([0.1, 100.0**2, 100.0**2, 0.5**2]),
        ),
    ],
)
@pytest.mark.parametrize(
    "sensor",
    [
        RangeBearingSensor(10.0, 0.01),
        RangeRateBearingSensor(10.0, 0.2, 0.01),
        AmbiguousBearingSensor(0.01),
    ],
)
def test_every_model_and_sensor_runs_and_stays_spd(model, x0, P, sensor):
    steps = simulate(
        model, x0, [(sensor, SENSOR_A), (sensor, SENSOR_B)], 10, np.random.default_rng(9)
    )
    ekf = ExtendedKalmanFilter(model, x0, P)
    for t, _, ms in steps:
        info = ekf.step(t, ms)
        assert np.isfinite(info.nis) and info.dof == 2 * sensor.dim_z
        assert np.all(np.isfinite(ekf.mean))
        assert np.linalg.eigvalsh(ekf.cov)[0] > 0.0
    # Position is tracked: the kinematics error is within 5 sigma of the estimate's spread.
    truth_pv = model.kinematics(steps[-1][1])
    est_pv = model.kinematics(ekf.mean)
    J = model.kinematics_jacobian(ekf.mean)
    pos_var = np.diag(J @ ekf.cov @ J.T)[[0, 2]]
    assert np.all(np.abs(est_pv - truth_pv)[[0, 2]] < 5 * np.sqrt(pos_var) + 1.0)


def test_make_filter_and_shared_interface():
    model = NearlyConstantVelocity(0.1)
    config = TrackerConfig(filter="pf", particles=500)  # the scenario's tracker block
    rng = np.random.default_rng(0)
    ekf = make_filter("ekf", model, X0, P0, config, rng)
    pf = make_filter("pf", model, X0, P0, config, rng)
    assert isinstance(ekf, ExtendedKalmanFilter) and isinstance(pf, ParticleFilter)
    assert pf.particles.shape == (500, 4)
    m = Measurement(BearingSensor(0.01), SENSOR_A, [0.6], 7.0)
    for f in (ekf, pf):
        assert f.time == 0.0
        info = f.step(7.0, [m])
        assert isinstance(info, UpdateInfo) and f.time == 7.0 and info.time == 7.0
        assert f.mean.shape == (4,) and f.cov.shape == (4, 4)
    with pytest.raises(ValueError, match="tracker.filter: must be one of 'ekf' or 'pf'"):
        make_filter("ukf", model, X0, P0, config, rng)


def test_bad_inputs_raise_value_error_naming_the_argument():
    model = NearlyConstantVelocity(0.1)
    sensor = BearingSensor(0.01)
    with pytest.raises(ValueError, match="z"):
        Measurement(sensor, SENSOR_A, [math.nan], 0.0)
    with pytest.raises(ValueError, match="z"):
        Measurement(sensor, SENSOR_A, [0.1, 0.2], 0.0)
    with pytest.raises(ValueError, match="sensor_state"):
        Measurement(sensor, [0.0, 1.0], [0.1], 0.0)
    with pytest.raises(ValueError, match="time"):
        Measurement(sensor, SENSOR_A, [0.1], math.inf)
    with pytest.raises(ValueError, match="x0"):
        ExtendedKalmanFilter(model, X0[:3], P0)
    with pytest.raises(ValueError, match="x0"):
        ExtendedKalmanFilter(model, [1.0, math.nan, 0.0, 0.0], P0)
    with pytest.raises(ValueError, match="P0"):
        ExtendedKalmanFilter(model, X0, np.diag([1.0, -1.0, 1.0, 1.0]))
    ekf = ExtendedKalmanFilter(model, X0, P0, t0=10.0)
    with pytest.raises(ValueError, match="t"):
        ekf.predict(9.0)
    with pytest.raises(ValueError, match="t"):
        ekf.predict(math.nan)
    with pytest.raises(ValueError, match="measurements"):
        ekf.update([Measurement(sensor, SENSOR_A, [0.1], 11.0)])  # from the future
    with pytest.raises(ValueError, match="range"):
        at_target = np.array([X0[0], 0.0, X0[2], 0.0])
        ekf.update([Measurement(sensor, at_target, [0.1], 10.0)])
    # Nothing above changed the filter.
    assert ekf.time == 10.0
    np.testing.assert_array_equal(ekf.mean, X0)


def test_pda_update_with_the_callers_linearization_equals_its_own():
    """The tracker hands the EKF its scan's Jacobian and residuals: the same update, to the bit
    (they are the numbers pda_residuals computes)."""
    model = NearlyConstantVelocity(0.01)
    sensor = RangeBearingSensor(50.0, 0.02, 0.9, 100.0, 1e5)
    s = np.array([14000.0, 0.0, 8000.0, 0.0])
    x0, P0 = np.array([7000.0, 5.0, 8100.0, -3.0]), np.diag([1e4, 9.0, 1e4, 9.0])
    Z = np.array([[7010.0, math.pi - 0.012], [6900.0, math.pi - 0.02], [7050.0, -math.pi + 0.01]])
    beta = np.array([0.1, 0.5, 0.3, 0.1])
    own, given = ExtendedKalmanFilter(model, x0, P0), ExtendedKalmanFilter(model, x0, P0)
    for f in (own, given):
        f.predict(5.0)
    meas = [Measurement(sensor, s, z, 5.0, "radar") for z in Z]
    predicted = own.mean
    own.update_pda(meas, beta)
    H, nu = pda_residuals(given.mean, given.cov, Z, sensor, s, model)
    given.update_pda(meas, beta, linearization=(H, nu))
    assert np.array_equal(own.mean, given.mean) and np.array_equal(own.cov, given.cov)
    assert np.linalg.norm(own.mean - predicted) > 1.0  # it did update
    other = ExtendedKalmanFilter(model, x0, P0)
    other.predict(5.0)
    other.update_pda(meas, beta, linearization=(H, nu + np.array([10.0, 0.0])))  # and it uses them
    assert abs(other.mean[0] - own.mean[0]) > 1.0


@pytest.mark.parametrize("m", [1, 2, 5])
def test_stacked_pda_update_of_many_filters_equals_each_ones_own(m):
    """update_pda_many (the tracker's stacked EKF update of a scan) gives every filter the
    numbers its own update_pda gives, to the bit; a row with beta_0 = 1 keeps its prediction."""
    rng = np.random.default_rng(m)
    model = NearlyConstantVelocity(0.01)
    sensor = RangeBearingSensor(50.0, 0.02, 0.9, 100.0, 1e5)
    s = np.array([14000.0, 0.0, 8000.0, 0.0])
    G = 40
    X0 = np.column_stack(
        [
            rng.uniform(2e3, 9e3, G),
            rng.normal(0, 5, G),
            rng.uniform(2e3, 9e3, G),
            rng.normal(0, 5, G),
        ]
    )
    A = rng.standard_normal((G, 4, 4)) * [[30.0], [2.0], [30.0], [2.0]]
    P0 = A @ np.swapaxes(A, 1, 2) + np.eye(4)
    own = [ExtendedKalmanFilter(model, X0[g], P0[g]) for g in range(G)]
    many = [ExtendedKalmanFilter(model, X0[g], P0[g]) for g in range(G)]
    for f in own + many:
        f.predict(5.0)
    Z = sensor.measure(X0[:, None, :] + rng.normal(0, 60, (G, m, 4)), s)
    B = rng.dirichlet(np.ones(m + 1), G)
    B[3] = np.eye(m + 1)[0]  # no detection is its target's
    H = np.empty((G, 2, 4))
    nu = np.empty((G, m, 2))
    for g in range(G):
        meas = [Measurement(sensor, s, z, 5.0, "radar") for z in Z[g]]
        H[g], nu[g] = pda_residuals(many[g].mean, many[g].cov, Z[g], sensor, s, model)
        own[g].update_pda(meas, B[g])
    ExtendedKalmanFilter.update_pda_many(many, H, nu, B, sensor.R, "radar")
    for a, b in zip(own, many, strict=True):
        assert np.array_equal(a.mean, b.mean) and np.array_equal(a.cov, b.cov)
    predicted = ExtendedKalmanFilter(model, X0[3], P0[3])
    predicted.predict(5.0)
    assert np.array_equal(many[3].mean, predicted.mean)
    assert many[0].last_info.n_detections == m and many[0].last_info.sensor_ids == ("radar",) * m
    with pytest.raises(ValueError, match="beta"):
        ExtendedKalmanFilter.update_pda_many(many, H, nu, B * 1.1, sensor.R)


@pytest.mark.parametrize(
    "model",
    [
        NearlyConstantVelocity(0.01),
        NearlyConstantVelocityDiscrete(0.5, 0.5),
        CircularMotion(1e-3, 0.05),
    ],
    ids=["ncv", "ncv-discrete", "circular (nonlinear: one by one)"],
)
def test_predict_many_equals_each_filters_own_predict(model):
    """The tracker predicts all its EKF tracks at once: the numbers of each one's predict, to
    the bit, for filters at two different times (two stacked groups) and one already there."""
    rng = np.random.default_rng(4)
    n, G = model.dim, 30
    X0 = (
        rng.normal(0.0, 1.0, (G, n)) * np.r_[1e3, 5.0, 1e3, 5.0, 0.01][:n]
        + np.r_[5e3, 0.0, 5e3, 0.0, 0.05][:n]
    )
    A = rng.standard_normal((G, n, n))
    P0 = A @ np.swapaxes(A, 1, 2) + np.eye(n)
    t0 = np.where(np.arange(G) % 3 == 0, 5.0, 0.0)
    t0[1] = 10.0
    own = [ExtendedKalmanFilter(model, X0[g], P0[g], t0[g]) for g in range(G)]
    many = [ExtendedKalmanFilter(model, X0[g], P0[g], t0[g]) for g in range(G)]
    for f in own:
        f.predict(10.0)
    ExtendedKalmanFilter.predict_many(many, 10.0)
    for a, b in zip(own, many, strict=True):
        assert a.time == b.time == 10.0
        assert np.array_equal(a.mean, b.mean) and np.array_equal(a.cov, b.cov)
    assert not np.array_equal(many[2].mean, X0[2])  # it moved
    assert np.array_equal(many[1].mean, X0[1])  # already at t


def test_many_builds_the_filters_one_by_one_would_and_checks_the_stack():
    model = NearlyConstantVelocity(0.01)
    rng = np.random.default_rng(5)
    X0 = rng.normal(0.0, 1e3, (6, 4))
    A = rng.standard_normal((6, 4, 4))
    P0 = A @ np.swapaxes(A, 1, 2) + np.eye(4)
    P0[2, 0, 1] += 1e-13  # a round-off asymmetry, symmetrised the same way
    built = ExtendedKalmanFilter.many(model, X0, P0, 5.0)
    for g, f in enumerate(built):
        one = ExtendedKalmanFilter(model, X0[g], P0[g], 5.0)
        assert f.time == one.time == 5.0
        assert np.array_equal(f.mean, one.mean) and np.array_equal(f.cov, one.cov)
    built[0].predict(10.0)  # independent filters
    assert built[1].time == 5.0
    # the stacked reads are the filters' own moments, copies
    means, covs = ExtendedKalmanFilter.means_many(built), ExtendedKalmanFilter.covs_many(built)
    assert means.shape == (6, 4) and covs.shape == (6, 4, 4)
    for g, f in enumerate(built):
        assert np.array_equal(means[g], f.mean) and np.array_equal(covs[g], f.cov)
    means[0] += 1.0
    assert not np.array_equal(means[0], built[0].mean)
    bad = P0.copy()
    bad[4] = -np.eye(4)
    with pytest.raises(ValueError, match="P0"):
        ExtendedKalmanFilter.many(model, X0, bad, 5.0)
    with pytest.raises(ValueError, match="x0"):
        ExtendedKalmanFilter.many(model, X0[:, :3], P0, 5.0)
    with pytest.raises(ValueError, match="t0"):
        ExtendedKalmanFilter.many(model, X0, P0, math.nan)
