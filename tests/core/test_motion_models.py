"""Motion models: transitions, Jacobians vs finite differences, Q, sampling, kinematics."""

import math

import numpy as np
import pytest
from scipy.integrate import quad_vec, solve_ivp
from scipy.linalg import expm

from activetrack.models.motion import (
    CircularMotion,
    CircularMotionKnownOmega,
    ConstantTurn,
    NearlyConstantVelocity,
    NearlyConstantVelocityDiscrete,
)


def central_jacobian(f, x, h):
    """Central finite-difference Jacobian of f: (n,) -> (m,) with per-entry steps h (n,)."""
    cols = []
    for j in range(x.size):
        e = np.zeros_like(x)
        e[j] = h[j]
        cols.append((f(x + e) - f(x - e)) / (2 * h[j]))
    return np.stack(cols, axis=-1)


def assert_rows_close(J, J_fd, rtol=1e-6):
    """Each row agrees to rtol relative to that row's largest entry (rows differ in units)."""
    scale = np.maximum(np.max(np.abs(J), axis=-1, keepdims=True), 1e-300)
    assert np.all(np.abs(J - J_fd) <= rtol * scale), np.max(np.abs(J - J_fd) / scale)


def random_pv(rng, size=()):
    pos = rng.uniform(-500, 500, (*size, 2))
    vel = rng.uniform(-10, 10, (*size, 2))
    return np.stack([pos[..., 0], vel[..., 0], pos[..., 1], vel[..., 1]], axis=-1)


def random_circular(rng, size=(), omegas=None):
    psi = rng.uniform(-4, 4, size)
    p = rng.uniform(-100, 100, (*size, 2))
    omega = rng.uniform(-0.5, 0.5, size) if omegas is None else omegas
    v = rng.uniform(-3, 8, size)
    return np.stack([psi, p[..., 0], p[..., 1], omega, v], axis=-1)


MODELS = [
    NearlyConstantVelocity(q=0.3),
    NearlyConstantVelocityDiscrete(sigma_x=0.2, sigma_y=0.5),
    ConstantTurn(omega=0.2, q=0.4),
    ConstantTurn(omega=-1e-4, q=0.4),
    ConstantTurn(omega=0.0, q=0.4),
    CircularMotion(sigma_omega=0.01, sigma_v=0.3),
    CircularMotionKnownOmega(omega=0.15, sigma_v=0.3),
    CircularMotionKnownOmega(omega=0.0, sigma_v=0.3),
]


def random_state(model, rng, size=()):
    if model.dim == 4 and model.state_names[0] == "x":
        return random_pv(rng, size)
    x = random_circular(rng, size)
    return x if model.dim == 5 else x[..., [0, 1, 2, 4]]


def step_sizes(x):
    return 1e-6 * np.maximum(1.0, np.abs(x))


# ---------------------------------------------------------------- NCV (Hernandez / Ramdaras)


def test_ncv_matches_closed_form():
    q, T = 0.7, 5.0
    m = NearlyConstantVelocity(q)
    Q1 = q * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    expected = np.zeros((4, 4))
    expected[:2, :2] = expected[2:, 2:] = Q1
    np.testing.assert_allclose(m.process_noise(T), expected, rtol=1e-15)
    F = m.transition_matrix(T)
    np.testing.assert_array_equal(F, [[1, T, 0, 0], [0, 1, 0, 0], [0, 0, 1, T], [0, 0, 0, 1]])
    x = np.array([1000.0, -4.0, 1000.0, -4.0])  # pv order (x, xdot, y, ydot)
    np.testing.assert_allclose(m.propagate(x, T), [980.0, -4.0, 980.0, -4.0])


def test_ncv_discrete_is_G_GT():
    T, sx, sy = 2.0, 0.3, 0.7
    m = NearlyConstantVelocityDiscrete(sx, sy)
    G = np.array([[0.5 * T**2 * sx, 0], [T * sx, 0], [0, 0.5 * T**2 * sy], [0, T * sy]])
    np.testing.assert_allclose(m.process_noise(T), G @ G.T, rtol=1e-15)
    # rank 2: the discrete form is a rank-one noise per axis
    assert np.linalg.matrix_rank(m.process_noise(T)) == 2


# ---------------------------------------------------------------- constant turn (Valverde B)


def ct_generator(omega):
    """Continuous-time matrix of Valverde eq. 32 for pv (x, xdot, y, ydot)."""
    return np.array([[0, 1, 0, 0], [0, 0, 0, -omega], [0, 0, 0, 1], [0, omega, 0, 0]], dtype=float)


@pytest.mark.parametrize("omega", [0.3, -0.05, 1e-3, 1e-7, 0.0, 2.5])
def test_ct_transition_is_matrix_exponential(omega):
    T = 1.7
    m = ConstantTurn(omega, q=1.0)
    np.testing.assert_allclose(m.transition_matrix(T), expm(ct_generator(omega) * T), atol=1e-14)


@pytest.mark.parametrize("omega", [0.3, -0.8, 0.05 / 1.3 * 0.999, 0.05 / 1.3 * 1.001, 1e-5, 0.0])
def test_ct_Q_matches_quadrature_of_eq37(omega):
    T, q = 1.3, 0.25
    A = ct_generator(omega)
    G = np.array([[0, 0], [1, 0], [0, 0], [0, 1]], dtype=float)

    def integrand(tau):  # Phi(T - xi) G q G^T Phi^T with tau = T - xi
        PG = expm(A * tau) @ G
        return q * PG @ PG.T

    Q_quad, _ = quad_vec(integrand, 0.0, T, epsabs=1e-14, epsrel=1e-12)
    Q = ConstantTurn(omega, q).process_noise(T)
    np.testing.assert_allclose(Q, Q_quad, rtol=1e-10, atol=1e-13 * np.max(np.abs(Q_quad)))


def test_ct_Q_tends_to_ncv_Q():
    T, q = 5.0, 0.1
    Q_ncv = NearlyConstantVelocity(q).process_noise(T)
    np.testing.assert_array_equal(ConstantTurn(0.0, q).process_noise(T), Q_ncv)
    prev = np.inf
    for omega in (1e-1, 1e-2, 1e-3, 1e-4):
        err = np.max(np.abs(ConstantTurn(omega, q).process_noise(T) - Q_ncv))
        assert err < prev
        prev = err
    # leading error is the omega * T^3 / 6 cross term
    assert prev == pytest.approx(q * 1e-4 * T**3 / 6, rel=1e-3)


def test_ct_series_continuous_across_threshold():
    """Series branch (|omega T| < 0.05) and closed form agree at the switch."""
    T = 1.0
    below = ConstantTurn(0.05 * (1 - 1e-9), 1.0)
    above = ConstantTurn(0.05 * (1 + 1e-9), 1.0)
    np.testing.assert_allclose(below.process_noise(T), above.process_noise(T), rtol=1e-8)
    np.testing.assert_allclose(below.transition_matrix(T), above.transition_matrix(T), rtol=1e-8)


def test_ct_follows_circle():
    """A turning target keeps its speed and returns to its start after one period."""
    omega = 0.1
    m = ConstantTurn(omega, q=0.0)
    x0 = np.array([10.0, 3.0, -5.0, 4.0])
    x = x0
    for _ in range(20):
        x = m.propagate(x, math.pi / omega / 10)
    np.testing.assert_allclose(x, x0, atol=1e-9)
    half = m.propagate(x0, math.pi / omega)
    np.testing.assert_allclose(half[[1, 3]], -x0[[1, 3]], atol=1e-12)
    # turn centre = p + (-ydot, xdot)/omega; the half-turn point is its mirror image
    centre = x0[[0, 2]] + np.array([-x0[3], x0[1]]) / omega
    np.testing.assert_allclose(half[[0, 2]], 2 * centre - x0[[0, 2]], atol=1e-9)


# ---------------------------------------------------------------- circular motion (Valverde A)


def test_circular_propagate_matches_ode_eq15():
    """Eq. 24 is the exact solution of the kinematics eq. 15."""
    rng = np.random.default_rng(3)
    m = CircularMotion(0.0, 0.0)
    for x0 in random_circular(rng, (4,)):
        T = 2.3

        def rhs(t, s, omega=x0[3], v=x0[4]):
            return [omega, v * np.cos(s[0]), v * np.sin(s[0])]

        sol = solve_ivp(rhs, (0, T), x0[:3], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(m.propagate(x0, T)[:3], sol.y[:, -1], rtol=1e-9, atol=1e-8)


def test_circular_agrees_with_constant_turn():
    """Known-omega circular motion and constant turn describe the same path (pv)."""
    omega, T = 0.12, 3.0
    cm = CircularMotionKnownOmega(omega, 0.0)
    ct = ConstantTurn(omega, 0.0)
    x = np.array([0.4, 12.0, -7.0, 2.5])
    pv = cm.kinematics(x)
    for _ in range(5):
        x, pv = cm.propagate(x, T), ct.propagate(pv, T)
        np.testing.assert_allclose(cm.kinematics(x), pv, atol=1e-11)
    full = CircularMotion(0.0, 0.0)
    xf = np.array([0.4, 12.0, -7.0, omega, 2.5])
    np.testing.assert_allclose(
        full.kinematics(full.propagate(xf, T)),
        ct.propagate(full.kinematics(xf), T),
        atol=1e-12,
    )


def test_circular_straight_line_at_zero_omega():
    m = CircularMotion(0.0, 0.0)
    x = np.array([math.pi / 6, 1.0, 2.0, 0.0, 4.0])
    np.testing.assert_allclose(
        m.propagate(x, 2.0), [math.pi / 6, 1 + 8 * math.cos(math.pi / 6), 2 + 4.0, 0, 4]
    )


def test_circular_Q_eq25():
    Q = CircularMotion(sigma_omega=0.02, sigma_v=0.5).process_noise(4.0)
    np.testing.assert_allclose(Q, np.diag([0, 0, 0, 4 * 0.02**2, 4 * 0.25]))
    Qk = CircularMotionKnownOmega(omega=0.1, sigma_v=0.5).process_noise(4.0)
    np.testing.assert_allclose(Qk, np.diag([0, 0, 0, 1.0]))


# ---------------------------------------------------------------- generic member tests


@pytest.mark.parametrize("model", MODELS, ids=repr)
def test_jacobian_matches_central_differences(model):
    rng = np.random.default_rng(10)
    for T in (0.5, 5.0):
        for x in random_state(model, rng, (6,)):
            J = model.jacobian(x, T)
            J_fd = central_jacobian(lambda s, T=T: model.propagate(s, T), x, step_sizes(x))
            assert J.shape == (model.dim, model.dim)
            assert_rows_close(J, J_fd)


@pytest.mark.parametrize("omega", [0.0, 1e-9, -3e-3, 0.049, 0.051, 0.9])
def test_circular_jacobian_small_and_zero_omega(omega):
    """The series branch of the derived eq. 26-28 Jacobian, including omega = 0 exactly."""
    rng = np.random.default_rng(11)
    m = CircularMotion(0.01, 0.1)
    for x in random_circular(rng, (4,), omegas=np.full(4, omega)):
        J = m.jacobian(x, 1.0)
        J_fd = central_jacobian(lambda s: m.propagate(s, 1.0), x, step_sizes(x))
        assert_rows_close(J, J_fd)


@pytest.mark.parametrize("model", MODELS, ids=repr)
def test_kinematics_jacobian_matches_central_differences(model):
    rng = np.random.default_rng(12)
    for x in random_state(model, rng, (5,)):
        K = model.kinematics_jacobian(x)
        assert K.shape == (4, model.dim)
        assert_rows_close(K, central_jacobian(model.kinematics, x, step_sizes(x)))


@pytest.mark.parametrize("model", MODELS, ids=repr)
def test_batched_equals_loop(model):
    rng = np.random.default_rng(13)
    X = random_state(model, rng, (3, 5))
    T = 2.0
    P, J = model.propagate(X, T), model.jacobian(X, T)
    K, pv = model.kinematics_jacobian(X), model.kinematics(X)
    assert P.shape == (3, 5, model.dim) and J.shape == (3, 5, model.dim, model.dim)
    for i in range(3):
        for j in range(5):
            np.testing.assert_allclose(P[i, j], model.propagate(X[i, j], T), rtol=1e-14)
            np.testing.assert_allclose(J[i, j], model.jacobian(X[i, j], T), rtol=1e-14)
            np.testing.assert_allclose(K[i, j], model.kinematics_jacobian(X[i, j]), rtol=1e-14)
            np.testing.assert_allclose(pv[i, j], model.kinematics(X[i, j]), rtol=1e-14)


@pytest.mark.parametrize("model", MODELS, ids=repr)
@pytest.mark.parametrize("T", [0.0, 0.1, 5.0])
def test_Q_symmetric_psd(model, T):
    Q = model.process_noise(T)
    assert Q.shape == (model.dim, model.dim)
    np.testing.assert_array_equal(Q, Q.T)
    assert np.min(np.linalg.eigvalsh(Q)) >= -1e-12 * max(1.0, np.max(np.abs(Q)))
    if T == 0.0:
        np.testing.assert_array_equal(Q, 0.0)


@pytest.mark.parametrize("model", MODELS, ids=repr)
def test_sample_mean_and_covariance(model):
    rng = np.random.default_rng(14)
    x = random_state(model, np.random.default_rng(15))
    T, N = 2.0, 40_000
    X = model.sample(np.broadcast_to(x, (N, model.dim)), T, rng)
    Q, mean = model.process_noise(T), model.propagate(x, T)
    W = X - mean
    d = np.sqrt(np.diag(Q))
    # five-sigma Monte Carlo error of the sample mean and sample covariance
    assert np.all(np.abs(W.mean(axis=0)) <= 5 * d / math.sqrt(N) + 1e-12)
    C = W.T @ W / N
    se = np.sqrt((np.outer(d**2, d**2) + Q**2) / N)
    assert np.all(np.abs(C - Q) <= 5 * se + 1e-12)
    # components without noise are propagated exactly
    exact = d == 0
    np.testing.assert_allclose(W[:, exact], 0.0, atol=1e-9)


def test_sample_is_seeded():
    m = NearlyConstantVelocity(1.0)
    x = np.zeros((3, 4))
    a = m.sample(x, 1.0, np.random.default_rng(5))
    b = m.sample(x, 1.0, np.random.default_rng(5))
    np.testing.assert_array_equal(a, b)


def test_pv_models_kinematics_identity():
    x = np.array([1.0, 2.0, 3.0, 4.0])
    m = ConstantTurn(0.1, 1.0)
    np.testing.assert_array_equal(m.kinematics(x), x)
    np.testing.assert_array_equal(m.kinematics_jacobian(x), np.eye(4))
    cm = CircularMotion(0.1, 0.1)
    np.testing.assert_allclose(
        cm.kinematics([math.pi / 2, 1.0, 2.0, 0.3, 4.0]), [1.0, 0.0, 2.0, 4.0], atol=1e-15
    )


def test_model_attributes():
    assert NearlyConstantVelocity(1.0).state_names == ("x", "xdot", "y", "ydot")
    assert CircularMotion(0.1, 0.1).state_names == ("psi", "px", "py", "omega", "v")
    assert CircularMotionKnownOmega(0.1, 0.1).dim == 4
    assert NearlyConstantVelocity(1.0).is_linear and ConstantTurn(0.1, 1.0).is_linear
    assert not CircularMotion(0.1, 0.1).is_linear


@pytest.mark.parametrize(
    ("factory", "field"),
    [
        (lambda: NearlyConstantVelocity(-1.0), "q"),
        (lambda: NearlyConstantVelocity(np.nan), "q"),
        (lambda: NearlyConstantVelocityDiscrete(-0.1, 1.0), "sigma_x"),
        (lambda: NearlyConstantVelocityDiscrete(0.1, np.inf), "sigma_y"),
        (lambda: ConstantTurn(np.nan, 1.0), "omega"),
        (lambda: ConstantTurn(0.1, -1.0), "q"),
        (lambda: CircularMotion(-1.0, 0.1), "sigma_omega"),
        (lambda: CircularMotion(0.1, -1.0), "sigma_v"),
        (lambda: CircularMotionKnownOmega(np.inf, 0.1), "omega"),
    ],
)
def test_constructor_validation(factory, field):
    with pytest.raises(ValueError, match=field):
        factory()


def test_call_validation():
    m = NearlyConstantVelocity(1.0)
    with pytest.raises(ValueError, match="dt"):
        m.propagate(np.zeros(4), -1.0)
    with pytest.raises(ValueError, match="dt"):
        m.process_noise(np.nan)
    with pytest.raises(ValueError, match=r"x must have shape \(\.\.\., 4\)"):
        m.propagate(np.zeros(5), 1.0)
    with pytest.raises(ValueError, match="x must be finite"):
        CircularMotion(0.1, 0.1).jacobian([0, 0, np.nan, 0, 1], 1.0)
    with pytest.raises(ValueError, match="rng"):
        m.sample(np.zeros(4), 1.0, rng=42)


@pytest.mark.parametrize("theta", [0.03, -0.04, 0.0499])
def test_small_angle_series_matches_closed_forms(theta):
    """The series branch of the turn coefficients agrees with the closed forms to 1e-10 where
    the closed forms are still accurate (just inside the switch at |omega T| = 0.05)."""
    from activetrack.models._turn_terms import turn_terms

    T = 2.0
    w = theta / T
    closed = [
        math.sin(theta) / w,
        (1 - math.cos(theta)) / w,
        (1 - math.cos(theta)) / w**2,
        (theta - math.sin(theta)) / w**3,
        (theta * math.cos(theta) - math.sin(theta)) / w**2,
        (theta * math.sin(theta) - 1 + math.cos(theta)) / w**2,
    ]
    np.testing.assert_allclose(np.array(turn_terms(w, T), dtype=float), closed, rtol=1e-10)
