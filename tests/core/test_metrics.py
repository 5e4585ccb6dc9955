"""OSPA and GOSPA (activetrack.metrics) against brute force, hand-computed values and the axioms."""

import itertools
import math

import numpy as np
import pytest

import activetrack as at
from activetrack.metrics import GospaResult, gospa, gospa_over_time, ospa, ospa_over_time

TOL = 1e-12


def brute_ospa(X, Y, c, p):
    """Schuhmacher et al. (2008) eq. (3), minimising over every injection of the smaller set."""
    X, Y = (X, Y) if len(X) <= len(Y) else (Y, X)
    m, n = len(X), len(Y)
    if n == 0:
        return 0.0
    best = min(
        sum(min(c, math.dist(X[i], Y[j])) ** p for i, j in enumerate(perm))
        for perm in itertools.permutations(range(n), m)
    )
    return ((best + c**p * (n - m)) / n) ** (1 / p)


def brute_gospa_eq1(X, Y, c, p, alpha):
    """Rahmathullah et al. (2017) eq. (1): injections of the smaller set, cut-off distances."""
    X, Y = (X, Y) if len(X) <= len(Y) else (Y, X)
    m, n = len(X), len(Y)
    best = min(
        sum(min(c, math.dist(X[i], Y[j])) ** p for i, j in enumerate(perm))
        for perm in itertools.permutations(range(n), m)
    )
    return (best + c**p / alpha * (n - m)) ** (1 / p)


def brute_gospa_eq2(X, Y, c, p):
    """Rahmathullah et al. (2017) eq. (2), alpha = 2: every partial assignment gamma.

    Returns (distance, localisation, missed, false) of the minimising gamma.
    """
    m, n = len(X), len(Y)
    best = (math.inf, 0.0, 0, 0)
    for k in range(min(m, n) + 1):
        for rows in itertools.combinations(range(m), k):
            for cols in itertools.permutations(range(n), k):
                loc = sum(math.dist(X[i], Y[j]) ** p for i, j in zip(rows, cols, strict=True))
                total = loc + c**p / 2 * (m + n - 2 * k)
                if total < best[0]:
                    best = (total, loc, m - k, n - k)
    return (best[0] ** (1 / p), *best[1:])


def random_case(rng):
    d = int(rng.integers(1, 4))
    m, n = (int(k) for k in rng.integers(0, 6, size=2))
    X = rng.uniform(0.0, 3.0, size=(m, d))
    Y = rng.uniform(0.0, 3.0, size=(n, d))
    c = float(rng.choice([0.5, 1.0, 3.0]))
    p = float(rng.choice([1.0, 2.0, 3.5]))
    return X, Y, c, p


def test_ospa_equals_brute_force_on_random_sets():
    rng = np.random.default_rng(20080801)
    for _ in range(400):
        X, Y, c, p = random_case(rng)
        assert ospa(X, Y, c, p) == pytest.approx(brute_ospa(X, Y, c, p), abs=TOL, rel=TOL)


def test_gospa_alpha2_equals_brute_force_and_its_decomposition():
    rng = np.random.default_rng(20170710)
    for _ in range(400):
        X, Y, c, p = random_case(rng)
        res = gospa(X, Y, c, p)
        dist, loc, missed, false = brute_gospa_eq2(X, Y, c, p)
        assert res.distance == pytest.approx(dist, abs=TOL, rel=TOL)
        assert res.distance == pytest.approx(brute_gospa_eq1(X, Y, c, p, 2.0), abs=TOL, rel=TOL)
        assert res.localisation == pytest.approx(loc, abs=TOL, rel=TOL)
        assert (res.missed, res.false_tracks) == (missed, false)


@pytest.mark.parametrize("alpha", [0.5, 1.0, 1.7])
def test_gospa_other_alphas_equal_eq1_brute_force(alpha):
    rng = np.random.default_rng(int(alpha * 100))
    for _ in range(150):
        X, Y, c, p = random_case(rng)
        res = gospa(X, Y, c, p, alpha=alpha)
        assert res.distance == pytest.approx(brute_gospa_eq1(X, Y, c, p, alpha), abs=TOL, rel=TOL)
        assert res.missed == max(0, len(X) - len(Y))
        assert res.false_tracks == max(0, len(Y) - len(X))
        assert res.distance**p == pytest.approx(
            res.localisation + c**p / alpha * (res.missed + res.false_tracks), rel=TOL, abs=TOL
        )


def test_decomposition_adds_up_and_the_assignment_is_consistent():
    rng = np.random.default_rng(5)
    for _ in range(300):
        X, Y, c, p = random_case(rng)
        res = gospa(X, Y, c, p)
        assert res.distance**p == pytest.approx(
            res.localisation + c**p / 2 * (res.missed + res.false_tracks), rel=TOL, abs=TOL
        )
        pairs = res.assignment
        assert len(pairs) == len(X) - res.missed == len(Y) - res.false_tracks
        assert len({i for i, _ in pairs}) == len({j for _, j in pairs}) == len(pairs)
        assert [i for i, _ in pairs] == sorted(i for i, _ in pairs)
        dists = [math.dist(X[i], Y[j]) for i, j in pairs]
        assert all(dd < c for dd in dists)
        assert sum(dd**p for dd in dists) == pytest.approx(res.localisation, rel=TOL, abs=TOL)


@pytest.mark.parametrize("empty", [[], np.zeros((0, 2))])
def test_empty_sets(empty):
    c, p = 4.0, 2.0
    assert ospa(empty, empty, c, p) == 0.0
    assert gospa(empty, empty, c, p) == GospaResult(0.0, 0.0, 0, 0, ())
    Y = np.array([[0.0, 0.0], [1.0, 2.0], [5.0, 5.0]])
    assert ospa(empty, Y, c, p) == ospa(Y, empty, c, p) == c
    expected = (c**p / 2 * 3) ** (1 / p)  # sqrt(24)
    assert expected == pytest.approx(math.sqrt(24.0), rel=1e-15)
    assert gospa(empty, Y, c, p) == GospaResult(expected, 0.0, 0, 3, ())
    assert gospa(Y, empty, c, p) == GospaResult(expected, 0.0, 3, 0, ())


def test_one_point_each():
    x, y = [[0.0, 0.0]], [[3.0, 4.0]]  # distance 5
    for p in (1.0, 2.0, 3.0):
        assert ospa(x, y, 6.0, p) == pytest.approx(5.0, rel=1e-15)
        res = gospa(x, y, 6.0, p)
        assert res.distance == pytest.approx(5.0, rel=1e-15)
        assert res.localisation == pytest.approx(5.0**p, rel=1e-15)
        assert (res.missed, res.false_tracks, res.assignment) == (0, 0, ((0, 0),))
        # Beyond the cut-off: OSPA saturates at c; GOSPA counts one missed and one false.
        assert ospa(x, y, 2.0, p) == 2.0
        res = gospa(x, y, 2.0, p)
        assert res.distance == pytest.approx(2.0, rel=1e-15)  # (2^p / 2 * 2)^(1/p)
        assert (res.localisation, res.missed, res.false_tracks, res.assignment) == (0, 1, 1, ())


def test_worked_example_with_a_missed_target():
    X = [[0.0, 0.0], [10.0, 0.0]]
    Y = [[1.0, 0.0]]
    assert ospa(X, Y, 5.0, 2.0) == pytest.approx(math.sqrt((1 + 25) / 2), rel=1e-15)
    res = gospa(X, Y, 5.0, 2.0)
    assert res.distance == pytest.approx(math.sqrt(1 + 25 / 2), rel=1e-15)
    assert (res.localisation, res.missed, res.false_tracks) == (1.0, 1, 0)
    assert res.assignment == ((0, 0),)
    # p = 1, alpha = 1: 1 + 5 * 1
    assert gospa(X, Y, 5.0, 1.0, alpha=1.0).distance == pytest.approx(6.0, rel=1e-15)


def test_the_optimal_assignment_is_not_the_greedy_one():
    # Greedy would pair x0 with y0 (distance 1) and leave x1 with y1 (distance 3): 1 + 9 = 10;
    # the optimum is x0-y1, x1-y0 at 2 each: 4 + 4 = 8.
    X = [[0.0], [3.0]]
    Y = [[1.0], [-2.0]]
    assert ospa(X, Y, 10.0, 2.0) == pytest.approx(math.sqrt(8 / 2), rel=1e-15)
    res = gospa(X, Y, 10.0, 2.0)
    assert res.distance == pytest.approx(math.sqrt(8), rel=1e-15)
    assert res.assignment == ((0, 1), (1, 0))


def random_sets(rng, k):
    d = int(rng.integers(1, 4))
    return [rng.uniform(0.0, 3.0, size=(int(rng.integers(0, 6)), d)) for _ in range(k)]


def test_metric_axioms_on_random_sets():
    rng = np.random.default_rng(42)
    for _ in range(300):
        X, Y, Z = random_sets(rng, 3)
        c = float(rng.choice([0.5, 1.0, 3.0]))
        p = float(rng.choice([1.0, 2.0, 3.5]))
        for alpha in (1.0, 2.0):
            xy, yx = gospa(X, Y, c, p, alpha).distance, gospa(Y, X, c, p, alpha).distance
            yz, xz = gospa(Y, Z, c, p, alpha).distance, gospa(X, Z, c, p, alpha).distance
            assert xy == pytest.approx(yx, abs=TOL)
            assert gospa(X, X, c, p, alpha).distance == 0.0
            assert xz <= xy + yz + TOL
        assert ospa(X, Y, c, p) == pytest.approx(ospa(Y, X, c, p), abs=TOL)
        assert ospa(X, X, c, p) == 0.0
        assert ospa(X, Z, c, p) <= ospa(X, Y, c, p) + ospa(Y, Z, c, p) + TOL
        assert 0.0 <= ospa(X, Y, c, p) <= c + TOL
        if len(X) or len(Y):  # distinct sets (continuous draws) are at a positive distance
            assert ospa(X, Y, c, p) > 0.0 and gospa(X, Y, c, p).distance > 0.0


def test_invariant_to_the_order_of_the_points():
    rng = np.random.default_rng(7)
    X, Y = rng.uniform(0, 3, size=(5, 2)), rng.uniform(0, 3, size=(4, 2))
    Xp, Yp = X[rng.permutation(5)], Y[rng.permutation(4)]
    assert ospa(Xp, Yp, 1.0, 2.0) == pytest.approx(ospa(X, Y, 1.0, 2.0), abs=TOL)
    assert gospa(Xp, Yp, 1.0, 2.0).distance == pytest.approx(gospa(X, Y, 1.0, 2.0).distance)


def test_cutoff_saturation():
    rng = np.random.default_rng(11)
    X = rng.uniform(0.0, 1.0, size=(3, 2))
    Y = rng.uniform(0.0, 1.0, size=(5, 2))
    c, p = 2.0, 2.0
    for shift in (10.0, 1e3, 1e6):  # every pair beyond c: the values stop growing
        assert ospa(X, Y + shift, c, p) == c
        res = gospa(X, Y + shift, c, p)
        assert res.distance == pytest.approx((c**p / 2 * 8) ** (1 / p), rel=1e-15)
        assert (res.localisation, res.missed, res.false_tracks) == (0.0, 3, 5)
    # Unshifted, every pair is closer than c (all points in the unit square): only the two
    # surplus estimates are false tracks.
    near = gospa(X, Y, c, p)
    assert near.missed == 0 and near.false_tracks == 2
    # A huge cut-off leaves every distance uncut: shifting every point by (0.3, 0.4), p = 1,
    # gives the mean shift length 0.5 (no other assignment is cheaper, by the triangle
    # inequality on the sum).
    big = ospa(X, X + np.array([0.3, 0.4]), 1e9, 1.0)
    assert big == pytest.approx(0.5, rel=1e-12)


def test_over_time_matches_the_per_epoch_values():
    rng = np.random.default_rng(3)
    truths = [rng.uniform(0, 3, size=(k, 2)) for k in (2, 0, 3, 2, 4)]
    estimates = [rng.uniform(0, 3, size=(k, 2)) for k in (3, 1, 0, 2, 4)]
    o = ospa_over_time(truths, estimates, 1.5, 2.0)
    g = gospa_over_time(truths, estimates, 1.5, 2.0)
    g1 = gospa_over_time(truths, estimates, 1.5, 2.0, alpha=1.0)
    assert o.shape == g.shape == g1.shape == (5,)
    for k in range(5):
        assert o[k] == ospa(truths[k], estimates[k], 1.5, 2.0)
        assert g[k] == gospa(truths[k], estimates[k], 1.5, 2.0).distance
        assert g1[k] == gospa(truths[k], estimates[k], 1.5, 2.0, 1.0).distance
    assert ospa_over_time([], [], 1.0, 1.0).shape == (0,)
    with pytest.raises(ValueError, match="same length K.*got 5 truths and 4 estimates"):
        gospa_over_time(truths, estimates[:4], 1.5, 2.0)


@pytest.mark.parametrize("fn", [ospa, lambda X, Y, c, p: gospa(X, Y, c, p)])
def test_bad_arguments_name_the_argument_and_range(fn):
    X, Y = [[0.0, 0.0]], [[1.0, 1.0]]
    for c in (0.0, -1.0, math.nan, math.inf, "x"):
        with pytest.raises(ValueError, match="^c must be"):
            fn(X, Y, c, 2.0)
    for p in (0.5, 0.0, math.inf, math.nan):
        with pytest.raises(ValueError, match=r"^p must be in \[1.0, inf\)"):
            fn(X, Y, 1.0, p)
    with pytest.raises(ValueError, match="same dimension d.*X of shape \\(1, 2\\).*\\(1, 3\\)"):
        fn(X, [[1.0, 1.0, 1.0]], 1.0, 2.0)
    with pytest.raises(ValueError, match=r"^X must be a set of points of shape \(k, d\)"):
        fn([0.0, 0.0], Y, 1.0, 2.0)
    with pytest.raises(ValueError, match=r"^Y must be a set of points.*shape \(2, 1, 2\)"):
        fn(X, np.zeros((2, 1, 2)), 1.0, 2.0)
    with pytest.raises(ValueError, match="^Y must be finite"):
        fn(X, [[math.nan, 0.0]], 1.0, 2.0)


def test_bad_alpha():
    for alpha in (0.0, -1.0, 2.5, math.nan):
        with pytest.raises(ValueError, match=r"^alpha must be in \(0.0, 2.0\]"):
            gospa([[0.0]], [[1.0]], 1.0, 2.0, alpha=alpha)


def test_exported_lazily_from_the_package():
    assert at.ospa is ospa and at.gospa is gospa and at.GospaResult is GospaResult
    assert at.ospa_over_time is ospa_over_time and at.gospa_over_time is gospa_over_time


# --- which tracks to report (tracker.tracks.report: gospa) -------------------------------------


def test_gospa_reported_picks_the_lower_expected_cost_by_brute_force():
    """Reported: r L + (1 - r) k; left out: r k (k = c^p / alpha, L = E[min(d, c)^p]); the
    rule reports exactly where the first is lower, over a grid of r and spreads, p 1 and 2."""
    from activetrack.metrics import GospaWeights, expected_localisation, gospa_reported

    r = np.linspace(0.0, 1.0, 41)[:, None]
    m = np.array([0.0, 1e2, 1e4, 5e4, 1e5, 2e5, 1e6])[None, :]
    for w in (GospaWeights(500.0, 2.0, 2.0), GospaWeights(300.0, 1.0, 1.5)):
        k, L = w.cardinality, expected_localisation(m, w.c, w.p)
        reported, left_out = r * L + (1 - r) * k, r * k
        clear = np.abs(reported - left_out) > 1e-9 * k  # ties either way
        got = np.broadcast_to(gospa_reported(r, m, w), clear.shape)
        assert np.array_equal(got[clear], (reported < left_out)[clear])


def test_gospa_reported_is_r_above_one_half_for_a_point_and_never_past_the_cutoff():
    from activetrack.metrics import GospaWeights, gospa_reported

    w = GospaWeights(500.0, 2.0, 2.0)
    assert gospa_reported([0.49, 0.5, 0.51, 1.0], 0.0, w).tolist() == [False, False, True, True]
    # L = m (1 - exp(-c^2 / m)) reaches k = c^2 / 2 at m = 0.628 c^2: beyond, not even at r = 1
    assert not gospa_reported(1.0, 0.64 * 500.0**2, w)
    assert gospa_reported(1.0, 0.62 * 500.0**2, w)
