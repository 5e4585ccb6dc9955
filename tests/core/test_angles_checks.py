"""Angle wrapping and argument checks (activetrack.angles, activetrack.checks)."""

import math

import numpy as np
import pytest

from activetrack.angles import angle_diff, within_angle, wrap_angle, wrap_half_angle
from activetrack.checks import (
    require_finite,
    require_in_range,
    require_nonnegative,
    require_positive,
    require_psd,
    require_spd,
    symmetrize,
)


def test_wrap_angle_known_values():
    a = np.array([0.0, math.pi, -math.pi, 3 * math.pi / 2, -3 * math.pi / 2, 7.0, 2 * math.pi])
    expected = np.array([0.0, -math.pi, -math.pi, -math.pi / 2, math.pi / 2, 7.0 - 2 * math.pi, 0])
    np.testing.assert_allclose(wrap_angle(a), expected, atol=1e-15)


def test_wrap_angle_interval_and_congruence():
    rng = np.random.default_rng(1)
    a = rng.uniform(-50, 50, size=10_000)
    w = wrap_angle(a)
    assert np.all(w >= -math.pi) and np.all(w < math.pi)
    k = (a - w) / (2 * math.pi)
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)


def test_wrap_angle_just_below_pi_stays_half_open():
    a = np.nextafter(math.pi, 0.0)
    assert wrap_angle(a) < math.pi
    assert wrap_angle(-math.pi) == -math.pi
    assert wrap_angle(math.pi) == -math.pi


def test_wrap_half_angle_modulo_pi():
    rng = np.random.default_rng(2)
    a = rng.uniform(-20, 20, size=10_000)
    w = wrap_half_angle(a)
    assert np.all(w >= -math.pi / 2) and np.all(w < math.pi / 2)
    k = (a - w) / math.pi
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)
    assert wrap_half_angle(math.pi / 2) == pytest.approx(-math.pi / 2)
    assert wrap_half_angle(0.75 * math.pi) == pytest.approx(-0.25 * math.pi)


def test_angle_diff_across_wrap():
    assert angle_diff(math.pi - 0.1, -math.pi + 0.1) == pytest.approx(-0.2)
    assert angle_diff(-math.pi + 0.1, math.pi - 0.1) == pytest.approx(0.2)


def _within_directly(a, c, half):
    return np.abs(wrap_angle(np.asarray(a)[None, :] - np.asarray(c)[:, None])) <= half


@pytest.mark.parametrize("half", [1e-7, 0.05, 0.1, 1.0, 3.0, math.pi - 1e-12])
def test_within_angle_is_the_wrapped_test_to_the_bit_at_every_edge(half):
    """Cells exactly at a beam's edge (c +- half, rounded), a hair inside and outside it,
    across the +-pi cut, and at random: the cosine test decides every pair as the wrapped
    difference does."""
    rng = np.random.default_rng(20261128)
    c = np.concatenate([rng.uniform(-math.pi, math.pi, 40), [-math.pi, math.pi - 1e-15, 0.0]])
    edges = np.concatenate([c + half, c - half])
    a = np.concatenate(
        [
            rng.uniform(-4.0, 4.0, 2000),
            edges,
            np.nextafter(edges, np.inf),
            np.nextafter(edges, -np.inf),
            edges + 2.0 * math.pi,
            edges - 2.0 * math.pi,
            edges + 1e-12,
            edges - 1e-12,
        ]
    )
    got = within_angle(a, c, half)
    assert got.shape == (c.size, a.size)
    assert np.array_equal(got, _within_directly(a, c, half))
    assert got.any() and not got.all()


def test_within_angle_a_half_width_of_pi_or_more_holds_every_angle_and_a_negative_one_none():
    a = np.linspace(-10.0, 10.0, 101)
    assert within_angle(a, [0.0, 2.0], math.pi).all()
    assert not within_angle(a, [0.0, 2.0], -0.1).any()
    assert not within_angle([math.nan], [0.0], 1.0).any()
    assert np.array_equal(
        within_angle(a, [1.0], math.pi - 1e-9), _within_directly(a, [1.0], math.pi - 1e-9)
    )


def test_require_finite():
    np.testing.assert_array_equal(require_finite("x", [1, 2]), [1.0, 2.0])
    with pytest.raises(ValueError, match="x_state"):
        require_finite("x_state", [1.0, np.nan])
    with pytest.raises(ValueError, match="P"):
        require_finite("P", [[np.inf]])
    with pytest.raises(ValueError, match="z"):
        require_finite("z", "abc")


def test_require_positive_and_nonnegative():
    assert require_positive("sigma", 2) == 2.0
    for bad in (0.0, -1.0, np.nan, np.inf, "x"):
        with pytest.raises(ValueError, match="sigma"):
            require_positive("sigma", bad)
    assert require_nonnegative("q", 0) == 0.0
    for bad in (-1e-12, np.nan, np.inf):
        with pytest.raises(ValueError, match=r"q.*>= 0"):
            require_nonnegative("q", bad)


def test_require_in_range_bounds():
    assert require_in_range("pd", 1.0, 0.0, 1.0, lo_inclusive=False) == 1.0
    with pytest.raises(ValueError, match=r"pd must be in \(0.0, 1.0\]"):
        require_in_range("pd", 0.0, 0.0, 1.0, lo_inclusive=False)
    with pytest.raises(ValueError, match="pd"):
        require_in_range("pd", 1.5, 0.0, 1.0)
    with pytest.raises(ValueError, match="pd"):
        require_in_range("pd", np.nan, 0.0, 1.0)
    assert require_in_range("r_max", np.inf, 0.0, np.inf) == np.inf
    with pytest.raises(ValueError, match="r_min"):
        require_in_range("r_min", np.inf, 0.0, np.inf, hi_inclusive=False)


def test_symmetrize_batched():
    A = np.arange(8.0).reshape(2, 2, 2)
    S = symmetrize(A)
    np.testing.assert_array_equal(S, np.swapaxes(S, -1, -2))
    np.testing.assert_array_equal(S[1], [[4.0, 5.5], [5.5, 7.0]])


def test_require_spd_and_psd():
    P = np.array([[2.0, 0.5], [0.5, 1.0]])
    np.testing.assert_array_equal(require_spd("P0", P), P)
    np.testing.assert_array_equal(require_spd("P0", np.stack([P, 2 * P])), np.stack([P, 2 * P]))
    with pytest.raises(ValueError, match=r"P0.*positive definite"):
        require_spd("P0", np.diag([1.0, 0.0]))
    with pytest.raises(ValueError, match=r"P0.*symmetric"):
        require_spd("P0", [[1.0, 0.2], [0.0, 1.0]])
    with pytest.raises(ValueError, match=r"P0.*square"):
        require_spd("P0", np.ones((2, 3)))
    with pytest.raises(ValueError, match="P0"):
        require_spd("P0", [[np.nan, 0.0], [0.0, 1.0]])
    np.testing.assert_array_equal(require_psd("Q", np.diag([1.0, 0.0])), np.diag([1.0, 0.0]))
    with pytest.raises(ValueError, match=r"Q.*semi-definite"):
        require_psd("Q", np.diag([1.0, -1e-3]))


@pytest.mark.parametrize("bad", [0, 11, -1, 2.0, True, "3", None])
def test_require_int_names_the_field_and_the_range(bad):
    from activetrack.checks import require_int

    assert require_int("runs", 10, 1, 10) == 10
    with pytest.raises(ValueError, match=r"^runs: must be an integer in \[1, 10\], got "):
        require_int("runs", bad, 1, 10)
