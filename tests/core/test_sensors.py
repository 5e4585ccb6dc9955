"""Sensor models: measurements, analytic Jacobians vs wrapped central differences, R, noise,
detection range, residual wrapping, broadcasting and argument checks."""

import math

import numpy as np
import pytest

from activetrack.angles import wrap_half_angle
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
    state_jacobian,
)

SENSORS = [
    BearingSensor(sigma=0.02),
    AmbiguousBearingSensor(sigma=0.02),
    RangeBearingSensor(sigma_r=2.0, sigma_b=0.01),
    RangeRateBearingSensor(sigma_r=2.0, sigma_rr=0.5, sigma_b=0.01),
]


def wrapped_central_jacobian(sensor, f, x, h):
    """Central differences of f: (n,) -> (dim_z,), angle entries differenced with wrapping."""
    cols = []
    for j in range(x.size):
        e = np.zeros_like(x)
        e[j] = h[j]
        cols.append(sensor.residual(f(x + e), f(x - e)) / (2 * h[j]))
    return np.stack(cols, axis=-1)


def assert_rows_close(J, J_fd, rtol=1e-6):
    scale = np.maximum(np.max(np.abs(J), axis=-1, keepdims=True), 1e-300)
    assert np.all(np.abs(J - J_fd) <= rtol * scale), np.max(np.abs(J - J_fd) / scale)


def random_pv(rng, size=()):
    pos = rng.uniform(-500, 500, (*size, 2))
    vel = rng.uniform(-10, 10, (*size, 2))
    return np.stack([pos[..., 0], vel[..., 0], pos[..., 1], vel[..., 1]], axis=-1)


def near_wrap_pairs(rng, n):
    """Target/sensor pairs with the bearing within 1e-7 rad of +-pi (target west of sensor)."""
    s = random_pv(rng, (n,))
    t = s.copy()
    t[:, 0] -= rng.uniform(10, 300, n)
    t[:, 2] += rng.uniform(-1e-5, 1e-5, n)
    t[:, [1, 3]] = rng.uniform(-5, 5, (n, 2))
    return t, s


def test_known_values():
    t = np.array([3.0, 1.0, 4.0, -2.0])
    s = np.array([0.0, 0.5, 0.0, 0.5])
    b = math.atan2(4, 3)
    np.testing.assert_allclose(BearingSensor(0.1).measure(t, s), [b])
    np.testing.assert_allclose(RangeBearingSensor(1, 0.1).measure(t, s), [5.0, b])
    # relative velocity (0.5, -2.5) projected on (0.6, 0.8)
    np.testing.assert_allclose(RangeRateBearingSensor(1, 1, 0.1).measure(t, s), [5, -1.7, b])
    # west of the sensor, just below the x axis: bearing -> -pi side
    np.testing.assert_allclose(
        BearingSensor(0.1).measure([-1, 0, -1e-9, 0], [0, 0, 0, 0]), [-math.pi + 1e-9]
    )
    # exactly west is -pi in the half-open convention, and the line sensor says 0 there
    assert BearingSensor(0.1).measure([-1, 0, 0, 0], [0, 0, 0, 0])[0] == -math.pi
    np.testing.assert_allclose(
        AmbiguousBearingSensor(0.1).measure([-1, 0, -1, 0], [0, 0, 0, 0]), [math.pi / 4]
    )


def test_components_and_R():
    assert BearingSensor(0.1).components == ("bearing",)
    assert RangeBearingSensor(1, 0.1).components == ("range", "bearing")
    # Ramdaras eq. 10 order
    s = RangeRateBearingSensor(1.0, 0.2, 0.03)
    assert s.components == ("range", "range_rate", "bearing")
    assert s.dim_z == 3
    np.testing.assert_allclose(s.R, np.diag([1.0, 0.04, 0.0009]))
    np.testing.assert_allclose(RangeBearingSensor(2.0, 0.1).R, np.diag([4.0, 0.01]))
    np.testing.assert_allclose(BearingSensor(0.1).R, [[0.01]])
    assert [x.kind for x in SENSORS] == [
        "bearing",
        "ambiguous_bearing",
        "range_bearing",
        "range_rate_bearing",
    ]


def test_range_rate_is_time_derivative_of_range():
    """rdot equals d r / dt for target and sensor moving at their constant velocities."""
    rng = np.random.default_rng(20)
    sensor = RangeRateBearingSensor(1, 1, 0.1)
    for _ in range(5):
        t, s = random_pv(rng), random_pv(rng)

        def r(tau, t=t, s=s):
            pt, ps = t[[0, 2]] + tau * t[[1, 3]], s[[0, 2]] + tau * s[[1, 3]]
            return np.hypot(*(pt - ps))

        h = 1e-3
        assert sensor.measure(t, s)[1] == pytest.approx((r(h) - r(-h)) / (2 * h), rel=1e-7)


@pytest.mark.parametrize("sensor", SENSORS, ids=repr)
def test_jacobian_matches_wrapped_central_differences(sensor):
    rng = np.random.default_rng(21)
    wrap_t, wrap_s = near_wrap_pairs(rng, 4)
    targets = np.concatenate([random_pv(rng, (8,)), wrap_t])
    sensors = np.concatenate([random_pv(rng, (8,)), wrap_s])
    for t, s in zip(targets, sensors, strict=True):
        J = sensor.jacobian(t, s)
        assert J.shape == (sensor.dim_z, 4)
        h = 1e-6 * np.maximum(1.0, np.abs(t))
        J_fd = wrapped_central_jacobian(sensor, lambda x, s=s: sensor.measure(x, s), t, h)
        assert_rows_close(J, J_fd)


def test_near_wrap_measurements_straddle_pi():
    """The near-wrap cases really cross the +-pi cut, so an unwrapped difference would fail."""
    t, s = near_wrap_pairs(np.random.default_rng(22), 4)
    b = BearingSensor(0.1).measure(t, s)[:, 0]
    assert np.all(np.abs(np.abs(b) - math.pi) < 1e-6)
    assert np.any(b > 0) and np.any(b < 0)


def test_bearing_jacobian_hernandez_eq9_up_to_sign():
    t, s = np.array([30.0, 1.0, -40.0, 2.0]), np.array([0.0, 0.0, 0.0, 0.0])
    H = BearingSensor(0.1).jacobian(t, s)[0]
    r2 = 2500.0
    np.testing.assert_allclose(-H, [-40.0 / r2, 0, -30.0 / r2, 0])  # eq. 9 as printed


def test_valverde_eq14_polar_form():
    d, theta = 7.0, 2.1
    t = np.array([d * math.cos(theta), 0.3, d * math.sin(theta), -0.2])
    J = RangeBearingSensor(1, 0.1).jacobian(t, np.zeros(4))
    expected = [[math.cos(theta), math.sin(theta)], [-math.sin(theta) / d, math.cos(theta) / d]]
    np.testing.assert_allclose(J[:, [0, 2]], expected, rtol=1e-14)
    np.testing.assert_array_equal(J[:, [1, 3]], 0.0)


@pytest.mark.parametrize("sensor", SENSORS, ids=repr)
def test_broadcast_equals_loop(sensor):
    rng = np.random.default_rng(23)
    T = random_pv(rng, (6, 1))
    S = random_pv(rng, (1, 3))
    z, J, inside = sensor.measure(T, S), sensor.jacobian(T, S), sensor.in_range(T, S)
    assert z.shape == (6, 3, sensor.dim_z) and J.shape == (6, 3, sensor.dim_z, 4)
    assert inside.shape == (6, 3)
    for i in range(6):
        for c in range(3):
            np.testing.assert_allclose(z[i, c], sensor.measure(T[i, 0], S[0, c]), rtol=1e-14)
            np.testing.assert_allclose(J[i, c], sensor.jacobian(T[i, 0], S[0, c]), rtol=1e-14)


@pytest.mark.parametrize("sensor", SENSORS, ids=repr)
def test_zero_range_jacobian_raises(sensor):
    p = np.array([5.0, 1.0, -3.0, 0.0])
    with pytest.raises(ValueError, match=r"target_pv and sensor_pv.*range"):
        sensor.jacobian(np.stack([p + 1, p]), p)


def test_residual_wrapping():
    b = BearingSensor(0.1)
    np.testing.assert_allclose(b.residual([math.pi - 0.01], [-math.pi + 0.01]), [-0.02])
    rb = RangeBearingSensor(1, 0.1)
    np.testing.assert_allclose(rb.residual([10.0, -3.1], [4.0, 3.1]), [6.0, 2 * math.pi - 6.2])
    rrb = RangeRateBearingSensor(1, 1, 0.1)
    np.testing.assert_allclose(rrb.residual([1, 7.0, 3.0], [0, 0.0, -3.0]), [1, 7, 6 - 2 * math.pi])
    amb = AmbiguousBearingSensor(0.1)
    np.testing.assert_allclose(amb.residual([math.pi / 2 - 0.01], [-math.pi / 2 + 0.01]), [-0.02])
    np.testing.assert_allclose(amb.residual([1.0], [1.0 - math.pi]), [0.0], atol=1e-15)
    with pytest.raises(ValueError, match="z and zhat"):
        rb.residual([1.0], [1.0])


def test_ambiguous_is_bearing_modulo_pi():
    rng = np.random.default_rng(24)
    t, s = random_pv(rng, (200,)), random_pv(rng, (200,))
    za = AmbiguousBearingSensor(0.1).measure(t, s)[:, 0]
    zb = BearingSensor(0.1).measure(t, s)[:, 0]
    assert np.all((za >= -math.pi / 2) & (za < math.pi / 2))
    np.testing.assert_allclose(wrap_half_angle(zb - za), 0.0, atol=1e-12)
    np.testing.assert_array_equal(
        AmbiguousBearingSensor(0.1).jacobian(t, s), BearingSensor(0.1).jacobian(t, s)
    )


def test_in_range_indicator_inclusive():
    sensor = BearingSensor(0.1, r_min=10.0, r_max=100.0)
    s = np.zeros(4)
    ranges = np.array([0.0, 9.999, 10.0, 50.0, 100.0, 100.001])
    t = np.stack([ranges, 0 * ranges, 0 * ranges, 0 * ranges], axis=-1)
    np.testing.assert_array_equal(sensor.in_range(t, s), [0, 0, 1, 1, 1, 0])


@pytest.mark.parametrize("sensor", SENSORS, ids=repr)
def test_sample_noise_covariance(sensor):
    rng = np.random.default_rng(25)
    N = 40_000
    t = np.array([-200.0, 3.0, 1e-3, -1.0])  # bearing at the +-pi cut: noise must wrap
    s = np.array([0.0, 1.0, 0.0, 2.0])
    z = sensor.sample(np.broadcast_to(t, (N, 4)), s, rng)
    for i in sensor.angle_indices:
        half = sensor.angle_period / 2
        assert np.all((z[:, i] >= -half) & (z[:, i] < half))
    e = sensor.residual(z, sensor.measure(t, s))
    d = np.sqrt(np.diag(sensor.R))
    assert np.all(np.abs(e.mean(axis=0)) <= 5 * d / math.sqrt(N))
    C = e.T @ e / N
    se = np.sqrt((np.outer(d**2, d**2) + sensor.R**2) / N)
    assert np.all(np.abs(C - sensor.R) <= 5 * se)


def test_detect_frequency_matches_pd():
    sensor = RangeBearingSensor(1.0, 0.1, pd=0.7, r_min=5.0)
    rng = np.random.default_rng(26)
    N = 20_000
    far = sensor.detect(np.broadcast_to([100.0, 0, 0, 0], (N, 4)), np.zeros(4), rng)
    assert abs(far.mean() - 0.7) <= 5 * math.sqrt(0.7 * 0.3 / N)
    near = sensor.detect(np.broadcast_to([1.0, 0, 0, 0], (N, 4)), np.zeros(4), rng)
    assert not near.any()


def test_sample_is_seeded():
    s = RangeBearingSensor(1.0, 0.1)
    a = s.sample([10.0, 0, 5, 0], np.zeros(4), np.random.default_rng(3))
    b = s.sample([10.0, 0, 5, 0], np.zeros(4), np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    ("factory", "field"),
    [
        (lambda: BearingSensor(0.0), "sigma"),
        (lambda: BearingSensor(-1.0), "sigma"),
        (lambda: BearingSensor(np.nan), "sigma"),
        (lambda: BearingSensor(0.1, pd=0.0), "pd"),
        (lambda: BearingSensor(0.1, pd=1.01), "pd"),
        (lambda: BearingSensor(0.1, r_min=-1.0), "r_min"),
        (lambda: BearingSensor(0.1, r_min=5.0, r_max=5.0), "r_max"),
        (lambda: BearingSensor(0.1, r_max=np.nan), "r_max"),
        (lambda: AmbiguousBearingSensor(0.0), "sigma"),
        (lambda: RangeBearingSensor(0.0, 0.1), "sigma_r"),
        (lambda: RangeBearingSensor(1.0, -0.1), "sigma_b"),
        (lambda: RangeRateBearingSensor(1.0, 0.0, 0.1), "sigma_rr"),
        (lambda: RangeRateBearingSensor(1.0, 1.0, 0.1, pd=2.0), "pd"),
    ],
)
def test_constructor_validation(factory, field):
    with pytest.raises(ValueError, match=field):
        factory()


def test_call_validation():
    s = BearingSensor(0.1)
    with pytest.raises(ValueError, match="target_pv"):
        s.measure([np.nan, 0, 0, 0], np.zeros(4))
    with pytest.raises(ValueError, match="sensor_pv"):
        s.measure(np.ones(4), np.zeros(3))
    with pytest.raises(ValueError, match="broadcast"):
        s.measure(np.ones((2, 4)), np.zeros((3, 4)))
    with pytest.raises(ValueError, match="rng"):
        s.sample(np.ones(4), np.zeros(4), rng=None)
    with pytest.raises(ValueError, match="range"):
        RangeRateBearingSensor(1, 1, 0.1).measure(np.ones(4), np.ones(4))


# ---------------------------------------------------------------- state_jacobian

MODELS = [
    NearlyConstantVelocity(0.1),
    NearlyConstantVelocityDiscrete(0.1, 0.2),
    ConstantTurn(0.1, 0.1),
    CircularMotion(0.01, 0.1),
    CircularMotionKnownOmega(0.1, 0.1),
]


def random_model_state(model, rng, size=()):
    pv = random_pv(rng, size)
    if model.state_names[0] == "x":
        return pv
    psi = rng.uniform(-4, 4, size)
    v = rng.uniform(0.5, 8, size)
    cols = [psi, pv[..., 0], pv[..., 2]] + (
        [rng.uniform(-0.3, 0.3, size)] if model.dim == 5 else []
    )
    return np.stack([*cols, v], axis=-1)


@pytest.mark.parametrize("model", MODELS, ids=repr)
@pytest.mark.parametrize("sensor", SENSORS, ids=repr)
def test_state_jacobian_matches_central_differences(sensor, model):
    rng = np.random.default_rng(27)
    for x in random_model_state(model, rng, (5,)):
        s = random_pv(rng)
        H = state_jacobian(sensor, model, x, s)
        assert H.shape == (sensor.dim_z, model.dim)

        def h(state, s=s):
            return sensor.measure(model.kinematics(state), s)

        step = 1e-6 * np.maximum(1.0, np.abs(x))
        assert_rows_close(H, wrapped_central_jacobian(sensor, h, x, step))


@pytest.mark.parametrize("model", MODELS, ids=repr)
def test_state_jacobian_broadcasts(model):
    rng = np.random.default_rng(28)
    sensor = RangeRateBearingSensor(1.0, 0.1, 0.01)
    X = random_model_state(model, rng, (4, 1))
    S = random_pv(rng, (1, 3))
    H = state_jacobian(sensor, model, X, S)
    assert H.shape == (4, 3, 3, model.dim)
    for i in range(4):
        for c in range(3):
            np.testing.assert_allclose(
                H[i, c], state_jacobian(sensor, model, X[i, 0], S[0, c]), rtol=1e-14
            )
