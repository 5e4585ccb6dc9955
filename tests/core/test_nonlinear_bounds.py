"""Nonlinear bounds: Tichavsky PCRLB (Valverde eq. 56-65) and Taylor's CRLB (eq. 44-51)."""

import math
from dataclasses import dataclass

import numpy as np
import pytest

from activetrack.bounds import (
    covariance_bound,
    gaussian_samples,
    nominal_path,
    pcrlb_trajectory,
    taylor_crlb,
    taylor_information_initial,
    tichavsky_pcrlb,
)
from activetrack.models.base import jacobian_information
from activetrack.models.motion import CircularMotion, ConstantTurn, NearlyConstantVelocity
from activetrack.models.sensors import BearingSensor, RangeBearingSensor

DT = 1.0
USBL = RangeBearingSensor(sigma_r=0.5, sigma_b=math.radians(1.0))  # Valverde eq. 10-12
CT_X0 = np.array([50.0, 0.0, 0.0, 5.0])  # on a circle of radius 50 m at omega = 0.1 rad/s
CT_P0 = np.diag([1.0, 0.1, 1.0, 0.1])
CM_X0 = np.array([math.pi / 2, 50.0, 0.0, 0.1, 5.0])  # (psi, px, py, omega, v)
CM_P0 = np.diag([1e-3, 1.0, 1.0, 1e-4, 0.1])


def _still_sensor(n_steps, pv=(0.0, 0.0, -100.0, 0.0)):
    return np.tile(np.asarray(pv), (n_steps, 1))


@dataclass(frozen=True)
class FlooredNoise:
    """A model whose Q gets ``floor`` on the diagonal (to compare eq. 65 with q_floor)."""

    base: object
    floor: float

    def __getattr__(self, name):
        return getattr(self.base, name)

    def process_noise(self, dt, x=None):
        return self.base.process_noise(dt) + self.floor * np.eye(self.base.dim)


# --- Tichavsky recursion -----------------------------------------------------------------------


def test_tichavsky_with_linear_model_reduces_to_hernandez_eq3():
    model = NearlyConstantVelocity(q=0.02)
    K, M = 8, 300
    x0 = np.array([1000.0, -4.0, 1000.0, -4.0])
    P0 = np.diag([10.0, 1.0, 10.0, 1.0])
    rng = np.random.default_rng(21)
    X = gaussian_samples(x0, P0, M, rng)
    trajectories = [X]
    for _ in range(K):
        X = model.sample(X, 5.0, rng)
        trajectories.append(X)
    trajectories = np.stack(trajectories)
    sensors = [BearingSensor(0.01, pd=0.8, r_min=1310.0), RangeBearingSensor(10.0, 0.02)]
    paths = np.stack(
        [np.tile([1800.0, -40.0, 2000.0, -40.0], (K, 1)), np.tile([0.0, 0.0, 300.0, 0.0], (K, 1))],
        axis=1,
    )  # (K, S, 4)
    J_tich = tichavsky_pcrlb(
        model, sensors, paths, x0, P0, K, 5.0, M, None, trajectories=trajectories
    )
    F, Q = model.transition_matrix(5.0), model.process_noise(5.0)
    J_eq3 = pcrlb_trajectory(np.linalg.inv(P0), F, Q, trajectories[1:], sensors, paths)
    np.testing.assert_allclose(J_tich, J_eq3, rtol=1e-8, atol=1e-10 * np.abs(J_eq3).max())
    # The minimum range really removes samples at some epochs (so I_r is exercised).
    r = np.hypot(trajectories[1:, :, 0] - 1800.0, trajectories[1:, :, 2] - 2000.0)
    assert 0.0 < np.mean(r < 1310.0) < 1.0


@pytest.mark.parametrize(
    ("model", "x0", "P0"),
    [
        (ConstantTurn(omega=0.1, q=0.01), CT_X0, CT_P0),
        (FlooredNoise(CircularMotion(1e-3, 1e-2), 1e-4), CM_X0, CM_P0),
    ],
)
def test_tichavsky_on_one_nominal_trajectory_equals_valverde_eq65(model, x0, P0):
    # With a single (deterministic) trajectory the expectations of eq. 62-64 are point values
    # and eq. 56 reduces to eq. 65, which taylor_crlb(process_noise=True) evaluates.
    K = 10
    paths = _still_sensor(K)
    path = nominal_path(model, x0, K, DT)[:, None, :]  # (K + 1, M = 1, n)
    J_tich = tichavsky_pcrlb(model, USBL, paths, x0, P0, K, DT, 1, None, trajectories=path)
    J_65 = taylor_crlb(model, USBL, paths, x0, K, DT, P0=P0, process_noise=True)
    np.testing.assert_allclose(J_tich, J_65, rtol=1e-7, atol=1e-9 * np.abs(J_65).max())


def test_taylor_crlb_equals_tichavsky_with_vanishing_process_noise():
    # Constant turn (Valverde eq. 35): as Q -> 0 the Monte Carlo PCRLB tends to the CRLB of
    # Taylor's method along the nominal path; they differ only by the spread of the sampled
    # geometry (P0) in E[H^T R^-1 H].
    model = ConstantTurn(omega=0.1, q=1e-10)
    K = 20
    paths = _still_sensor(K)
    J_taylor = taylor_crlb(model, USBL, paths, CT_X0, K, DT, P0=CT_P0)
    J_tich = tichavsky_pcrlb(
        model, USBL, paths, CT_X0, CT_P0, K, DT, 2000, np.random.default_rng(4)
    )
    for J in (J_taylor, J_tich):
        assert np.all(np.linalg.eigvalsh(J) > 0)
    var_taylor = np.diagonal(covariance_bound(J_taylor), axis1=-2, axis2=-1)
    var_tich = np.diagonal(covariance_bound(J_tich), axis1=-2, axis2=-1)
    np.testing.assert_allclose(var_tich, var_taylor, rtol=0.03)
    # The measurements do work: the final x-velocity bound is far below its prior 0.1.
    assert var_taylor[-1, 1] < 0.01


def test_tichavsky_circular_motion_needs_q_floor_and_is_positive_definite():
    model = CircularMotion(sigma_omega=1e-3, sigma_v=1e-2)  # Q = blkdiag(0_3, ...) (eq. 25)
    K = 5
    paths = _still_sensor(K)
    with pytest.raises(ValueError, match="q_floor"):
        tichavsky_pcrlb(model, USBL, paths, CM_X0, CM_P0, K, DT, 50, np.random.default_rng(0))
    J = tichavsky_pcrlb(
        model, USBL, paths, CM_X0, CM_P0, K, DT, 200, np.random.default_rng(0), q_floor=1e-4
    )
    assert J.shape == (K, 5, 5)
    assert np.all(np.linalg.eigvalsh(J) > 0)
    # More information than the prior alone: the position bound beats P0's 1 m^2.
    bound = covariance_bound(J[-1])
    assert bound[1, 1] < 0.9 and bound[2, 2] < 0.9


# --- Taylor's method -------------------------------------------------------------------------


def test_taylor_recursion_equals_batch_information_about_x0():
    # Eq. 50 (information about x_k) vs eq. 46-48 (about x_0): J(x_0) = Phi_k0^T J_k Phi_k0.
    model = CircularMotion(1e-3, 1e-2)
    K = 8
    paths = _still_sensor(K)
    for P0 in (None, CM_P0):
        J_k = taylor_crlb(model, USBL, paths, CM_X0, K, DT, P0=P0)
        J_x0 = taylor_information_initial(model, USBL, paths, CM_X0, K, DT, P0=P0)
        path = nominal_path(model, CM_X0, K, DT)
        Phi = np.eye(5)
        for k in range(K):
            Phi = model.jacobian(path[k], DT) @ Phi
            np.testing.assert_allclose(
                Phi.T @ J_k[k] @ Phi, J_x0[k], rtol=1e-8, atol=1e-10 * np.abs(J_x0[k]).max()
            )


def test_taylor_crlb_rank_grows_to_full_with_measurements():
    # Circular motion, range-bearing: each epoch adds rank 2; the 5-state becomes observable
    # (Valverde Table I, v != 0 and omega != 0) at the third epoch without prior.
    J = taylor_crlb(CircularMotion(1e-3, 1e-2), USBL, _still_sensor(6), CM_X0, 6, DT)
    ranks = [np.linalg.matrix_rank(Jk, tol=1e-9 * np.abs(Jk).max()) for Jk in J]
    assert ranks[:3] == [2, 4, 5]
    assert np.all(np.linalg.eigvalsh(J[3:]) > 0)


def test_taylor_crlb_constant_velocity_analytic():
    # NCV without noise, unit-variance position sensor, no prior: after epochs 1 and 2 the
    # x-axis information about (x_2, xdot_2) is sum over rows (1, -T) and (1, 0).
    T = 2.0

    @dataclass(frozen=True)
    class UnitPosition:
        kind = "position"
        R = np.eye(2)
        pd = 1.0

        def jacobian(self, target_pv, sensor_pv):
            shape = np.broadcast_shapes(np.shape(target_pv), np.shape(sensor_pv))[:-1]
            return np.broadcast_to(np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]]), (*shape, 2, 4))

        def in_range(self, target_pv, sensor_pv):
            return np.ones(np.broadcast_shapes(np.shape(target_pv), np.shape(sensor_pv))[:-1], bool)

        # The PCRLB's hook: the Jacobian form of Hernandez eq. 8 (models.base).
        fisher_information = jacobian_information

    J = taylor_crlb(
        NearlyConstantVelocity(q=0.0), UnitPosition(), np.zeros((2, 4)), np.ones(4), 2, T
    )
    expected = np.array([[2.0, -T], [-T, T * T]])
    np.testing.assert_allclose(J[1][np.ix_([0, 1], [0, 1])], expected, atol=1e-12)
    np.testing.assert_allclose(J[1][np.ix_([2, 3], [2, 3])], expected, atol=1e-12)


def test_taylor_crlb_batched_over_candidate_paths():
    model = ConstantTurn(omega=0.1, q=0.0)
    K = 5
    paths = np.stack([_still_sensor(K, (0, 0, -100, 0)), _still_sensor(K, (80, 0, 30, 0))], 1)
    J = taylor_crlb(model, USBL, paths, CT_X0, K, DT, P0=CT_P0)
    assert J.shape == (K, 2, 4, 4)
    for c in range(2):
        J_c = taylor_crlb(model, USBL, paths[:, c], CT_X0, K, DT, P0=CT_P0)
        np.testing.assert_allclose(J[:, c], J_c, rtol=1e-12)


# --- bad inputs ------------------------------------------------------------------------------


def test_nonlinear_bounds_reject_bad_inputs():
    model = ConstantTurn(omega=0.1, q=0.01)
    paths = _still_sensor(3)
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="P0"):
        tichavsky_pcrlb(model, USBL, paths, CT_X0, -CT_P0, 3, DT, 10, rng)
    with pytest.raises(ValueError, match="P0"):
        taylor_crlb(model, USBL, paths, CT_X0, 3, DT, P0=np.diag([1.0, 0.0, 1.0, 1.0]))
    bad = paths.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="sensor_paths"):
        tichavsky_pcrlb(model, USBL, bad, CT_X0, CT_P0, 3, DT, 10, rng)
    with pytest.raises(ValueError, match="sensor_paths"):
        taylor_crlb(model, USBL, bad, CT_X0, 3, DT)
    with pytest.raises(ValueError, match="sensor_paths"):
        taylor_crlb(model, USBL, paths[:2], CT_X0, 3, DT)
    with pytest.raises(ValueError, match="n_mc"):
        tichavsky_pcrlb(model, USBL, paths, CT_X0, CT_P0, 3, DT, 0, rng)
    with pytest.raises(ValueError, match="x0"):
        taylor_crlb(model, USBL, paths, np.array([np.inf, 0, 0, 0]), 3, DT)
    with pytest.raises(ValueError, match="P0"):
        taylor_crlb(model, USBL, paths, CT_X0, 3, DT, process_noise=True)
