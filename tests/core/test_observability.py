"""Observability rank test (Valverde eq. 38) on cases with a known answer (Tables I-II)."""

import math

import numpy as np
import pytest

from activetrack.models.motion import (
    CircularMotion,
    CircularMotionKnownOmega,
    ConstantTurn,
    NearlyConstantVelocity,
)
from activetrack.models.sensors import BearingSensor, RangeBearingSensor, RangeRateBearingSensor
from activetrack.observability import observability_matrix, observability_rank

RB = RangeBearingSensor(sigma_r=1.0, sigma_b=0.01)
ORIGIN = np.zeros(4)


def circular_state(v, omega, psi=0.3, p=(20.0, 10.0)):
    return np.array([psi, p[0], p[1], omega, v])


def pv_state(v, psi=0.3, p=(20.0, 10.0)):
    return np.array([p[0], v * math.cos(psi), p[1], v * math.sin(psi)])


def test_matrix_matches_hand_built_linear_case():
    """For a linear model O = [H0; H1 F; H2 F^2] with H_k at the true positions."""
    model = NearlyConstantVelocity(0.0)
    sensor = RangeRateBearingSensor(1.0, 0.1, 0.01)
    x0 = np.array([100.0, -3.0, 50.0, 2.0])
    s = np.array([[0.0, 1.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0], [2.0, 1.0, 0.0, 0.0]])
    F = model.transition_matrix(1.0)
    O, traj = observability_matrix(model, sensor, x0, s, 1.0)
    xs = [x0, F @ x0, F @ F @ x0]
    expected = np.concatenate(
        [
            sensor.jacobian(x, sk) @ np.linalg.matrix_power(F, k)
            for k, (x, sk) in enumerate(zip(xs, s, strict=True))
        ]
    )
    np.testing.assert_allclose(O, expected, rtol=1e-14)
    np.testing.assert_allclose(traj, xs, rtol=1e-14)
    result = observability_rank(model, sensor, x0, s, 1.0)
    np.testing.assert_allclose(result.singular_values, np.linalg.svd(expected, compute_uv=False))
    assert result.rank == 4 and result.observable
    assert result.tol == pytest.approx(1e-9 * result.singular_values[0])


def test_bearing_only_stationary_sensor_cv_target_unobservable():
    """Bearings from a fixed sensor cannot fix the scale: rank 3, null vector = relative state."""
    x0 = np.array([100.0, -3.0, 50.0, 2.0])
    s = np.array([-7.0, 0.0, 4.0, 0.0])
    result = observability_rank(
        NearlyConstantVelocity(0.0), BearingSensor(0.01), x0, s, 1.0, n_steps=20
    )
    assert result.rank == 3 and not result.observable
    assert result.singular_values[-1] < 1e-12 * result.singular_values[0]
    _, _, Vt = np.linalg.svd(result.matrix)
    relative = x0 - s
    null = Vt[-1]
    assert abs(null @ relative) == pytest.approx(np.linalg.norm(relative), rel=1e-9)


def test_bearing_only_manoeuvring_sensor_observable():
    """A sensor that changes course (a manoeuvre) makes the CV target observable."""
    s = np.array([[t, 1.0, 0.0, 0.0] if t < 5 else [5.0, 0.0, t - 5.0, 1.0] for t in range(10)])
    result = observability_rank(
        NearlyConstantVelocity(0.0), BearingSensor(0.01), np.array([100.0, -3, 50, 2]), s, 1.0
    )
    assert result.rank == 4


def test_range_bearing_ncv_needs_two_epochs():
    x0 = np.array([100.0, -3.0, 50.0, 2.0])
    one = observability_rank(NearlyConstantVelocity(0.0), RB, x0, ORIGIN, 1.0, n_steps=1)
    two = observability_rank(NearlyConstantVelocity(0.0), RB, x0, ORIGIN, 1.0, n_steps=2)
    assert (one.rank, two.rank) == (2, 4)


# ---------------------------------------------------------------- Valverde Table I


def test_circular_zero_speed_rank3_table1():
    """v = 0: heading and turn rate do not affect the measurements (Table I: rank 3)."""
    result = observability_rank(
        CircularMotion(0.0, 0.0), RB, circular_state(0.0, 0.1), ORIGIN, 1.0, n_steps=10
    )
    assert result.rank == 3
    # the unobservable directions are exactly psi and omega
    np.testing.assert_array_equal(result.matrix[:, [0, 3]], 0.0)


@pytest.mark.parametrize("omega", [0.0, 0.1])
def test_circular_moving_target_full_rank_table1(omega):
    """v = 5 m/s (Table I last row, omega = 0: rank 5); also with omega = 0.1 rad/s."""
    result = observability_rank(
        CircularMotion(0.0, 0.0), RB, circular_state(5.0, omega), ORIGIN, 1.0, n_steps=10
    )
    assert result.rank == 5 and result.observable


def test_circular_needs_three_epochs():
    """Two range-bearing epochs give 4 equations for 5 unknowns."""
    x0 = circular_state(5.0, 0.1)
    ranks = [
        observability_rank(CircularMotion(0.0, 0.0), RB, x0, ORIGIN, 1.0, n_steps=k).rank
        for k in (1, 2, 3)
    ]
    assert ranks == [2, 4, 5]


def test_circular_small_dt_loses_observability_table1():
    """dt -> 0: O tends to stacked copies of H_0. With rtol = 1e-9, dt = 1e-6 s leaves rank 4
    (Table I's 'dt' row) and dt = 1e-12 s leaves rank(H) = 2."""
    x0 = circular_state(5.0, 0.1)
    model = CircularMotion(0.0, 0.0)
    assert observability_rank(model, RB, x0, ORIGIN, 1e-6, n_steps=10).rank == 4
    assert observability_rank(model, RB, x0, ORIGIN, 1e-12, n_steps=10).rank == 2


def test_circular_known_omega_zero_speed():
    """Known-omega variant at v = 0: only the heading is unobservable (rank 3 of 4)."""
    model = CircularMotionKnownOmega(0.1, 0.0)
    result = observability_rank(
        model, RB, np.array([0.3, 20.0, 10.0, 0.0]), ORIGIN, 1.0, n_steps=10
    )
    assert result.rank == 3
    np.testing.assert_array_equal(result.matrix[:, 0], 0.0)
    moving = observability_rank(
        model, RB, np.array([0.3, 20.0, 10.0, 5.0]), ORIGIN, 1.0, n_steps=10
    )
    assert moving.rank == 4


# ---------------------------------------------------------------- Valverde Table II


@pytest.mark.parametrize(("v", "omega"), [(0.0, 0.1), (5.0, 0.1), (5.0, 0.0)])
def test_constant_turn_full_rank_table2(v, omega):
    """Constant turn keeps rank 4 at v = 0 and for v = 5 m/s, omega = 0 (Table II)."""
    result = observability_rank(ConstantTurn(omega, 0.0), RB, pv_state(v), ORIGIN, 1.0, n_steps=10)
    assert result.rank == 4


def test_constant_turn_small_dt_rank2_table2():
    """dt -> 0: rank drops to rank(H) = 2 (Table II)."""
    result = observability_rank(
        ConstantTurn(0.1, 0.0), RB, pv_state(5.0), ORIGIN, 1e-12, n_steps=10
    )
    assert result.rank == 2
    # the lost singular values shrink with dt
    coarser = observability_rank(
        ConstantTurn(0.1, 0.0), RB, pv_state(5.0), ORIGIN, 1e-6, n_steps=10
    )
    assert result.singular_values[2] < 1e-5 * coarser.singular_values[2]


# ---------------------------------------------------------------- arguments


def test_argument_validation():
    model, x0 = NearlyConstantVelocity(0.0), np.array([1.0, 0.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="n_steps"):
        observability_rank(model, RB, x0, ORIGIN, 1.0)
    with pytest.raises(ValueError, match="n_steps"):
        observability_rank(model, RB, x0, ORIGIN, 1.0, n_steps=0)
    with pytest.raises(ValueError, match="n_steps"):
        observability_rank(model, RB, x0, np.zeros((3, 4)), 1.0, n_steps=2)
    with pytest.raises(ValueError, match="rtol"):
        observability_rank(model, RB, x0, ORIGIN, 1.0, n_steps=2, rtol=0.0)
    with pytest.raises(ValueError, match="x0"):
        observability_rank(model, RB, np.zeros(5), ORIGIN, 1.0, n_steps=2)
    with pytest.raises(ValueError, match="sensor_pv"):
        observability_rank(model, RB, x0, np.zeros((2, 3, 4)), 1.0)
    with pytest.raises(ValueError, match="dt"):
        observability_rank(model, RB, x0, ORIGIN, -1.0, n_steps=2)
