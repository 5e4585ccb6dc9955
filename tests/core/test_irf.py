"""Information reduction factor (Niu, Willett & Bar-Shalom 2001; Hernandez, Farina & Ristic 2006).

Checks: no clutter gives the closed form ``q = Pd F_{chi2, n+2}(g^2)`` (1 for Pd = 1 and a wide
gate), q falls as clutter grows, q in [0, 1], the high-clutter asymptote, the cache, input checks,
and a Monte Carlo estimate of the definition (expected squared score of the mixture likelihood,
differentiated numerically) against the quadrature; the tabulated form for arrays of densities
against the exact integral between its nodes.
"""

import itertools
import math

import numpy as np
import pytest
from scipy.special import gammainc
from scipy.stats import poisson

import activetrack.models.irf as irf_module
from activetrack.models.irf import (
    IRF_TABLE_RANGE,
    IRF_TABLE_TOLERANCE,
    information_reduction_factor,
    information_reduction_factors,
    irf_cache_clear,
    irf_cache_info,
)


def _chi2_cdf(x: float, k: int) -> float:
    return float(gammainc(k / 2, x / 2))


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_unity_without_clutter_and_pd_one(dim: int) -> None:
    assert information_reduction_factor(1.0, 0.0, 8.0, dim) == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("dim", [1, 2])
@pytest.mark.parametrize("pd", [0.3, 0.7, 0.9, 1.0])
@pytest.mark.parametrize("gate", [2.0, 3.0, 5.0])
def test_no_clutter_is_pd_times_truncated_second_moment(dim: int, pd: float, gate: float) -> None:
    # lambda = 0: s = nu for a detection in the gate, so q = Pd E[|nu|^2; |nu| <= g] / n
    # = Pd F_{chi2, n+2}(g^2) -> Pd for a wide gate (the paper's Pd scaling).
    expected = pd * _chi2_cdf(gate * gate, dim + 2)
    assert information_reduction_factor(pd, 0.0, gate, dim) == pytest.approx(expected, abs=1e-10)


@pytest.mark.parametrize("dim", [1, 2])
@pytest.mark.parametrize("pd", [0.6, 0.9, 1.0])
def test_decreases_monotonically_with_clutter(dim: int, pd: float) -> None:
    lams = [0.0, 1e-4, 1e-3, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 100.0]
    qs = [information_reduction_factor(pd, lam, 4.0, dim) for lam in lams]
    assert all(b < a for a, b in itertools.pairwise(qs)), qs
    assert qs[-1] < 0.01


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_within_unit_interval_and_below_clutter_free_value(dim: int) -> None:
    for pd in (0.0, 0.1, 0.5, 1.0):
        for lam in (0.0, 0.01, 1.0, 1e4):
            for gate in (0.5, 2.0, 4.0, 10.0):
                q = information_reduction_factor(pd, lam, gate, dim)
                assert 0.0 <= q <= 1.0
                assert q <= pd * _chi2_cdf(gate * gate, dim + 2) + 1e-12
    assert information_reduction_factor(0.0, 0.5, 3.0, dim) == 0.0


@pytest.mark.parametrize("dim", [1, 2])
def test_high_clutter_asymptote(dim: int) -> None:
    # lambda -> inf: s ~ Pd sum_i N(nu_i) nu_i / lambda, so q ~ Pd^2 int N^2 |nu|^2 / (n lambda);
    # N^2 = (4 pi)^{-n/2} N(0, I/2), whose E|nu|^2 is n/2 (wide gate).
    lam, pd = 1e3, 0.8
    expected = pd**2 * (4 * math.pi) ** (-dim / 2) * 0.5 / lam
    assert information_reduction_factor(pd, lam, 5.0, dim) == pytest.approx(expected, rel=1e-3)


def test_figures_at_pd_one() -> None:
    # Regression figures of this implementation (quadrature converged to ~1e-12), Pd = 1.
    assert information_reduction_factor(1.0, 0.1, 4.0, 1) == pytest.approx(0.746343, abs=1e-6)
    assert information_reduction_factor(1.0, 0.01, 3.0, 2) == pytest.approx(0.831041, abs=1e-6)


def test_cache_hits_and_identical_values() -> None:
    irf_cache_clear()
    first = information_reduction_factor(0.9, 0.02, 3.5, 2)
    info = irf_cache_info()
    assert (info.hits, info.misses) == (0, 1)
    again = information_reduction_factor(0.9, 0.02, 3.5, 2)
    # Inputs are rounded for the key: a round-off-level change hits the same entry.
    nudged = information_reduction_factor(0.9 + 1e-13, 0.02 * (1 + 1e-12), 3.5, 2)
    info = irf_cache_info()
    assert again == first and nudged == first
    assert (info.hits, info.misses) == (2, 1)


def test_shared_time_integrals_change_no_bit() -> None:
    # Densities whose clutter rate is <= 1 share the lambda-free integrals (one grid in log t):
    # a value is the same whether it is computed first or from integrals another filled.
    irf_cache_clear()
    first = information_reduction_factor(0.9, 1e-4, 3.5, 2)
    irf_cache_clear()
    others = [information_reduction_factor(pd, 1e-3, 3.5, 2) for pd in (0.5, 0.7)]
    after = information_reduction_factor(0.9, 1e-4, 3.5, 2)
    assert irf_module._time_integrals.cache_info().hits == 2  # computed once, shared twice
    assert after == first and 0.85 < first < 0.9 and others[0] < others[1] < first
    # A high density has its own grid (it starts lower in log t).
    assert information_reduction_factor(0.9, 10.0, 3.5, 2) < 0.1
    assert irf_module._time_integrals.cache_info().misses == 2


def test_table_nodes_kept_on_disk_give_the_same_bits(tmp_path, monkeypatch) -> None:
    # A table's exact nodes are kept between processes; read back they are the computed bits,
    # and a damaged file is computed around (and written again), never trusted.
    monkeypatch.setattr(irf_module, "IRF_TABLE_CACHE", tmp_path)
    lam = np.array([3e-4, 0.02, 5.0])
    irf_cache_clear()
    computed = information_reduction_factors(0.85, lam, 3.5, 2)
    (stored,) = tmp_path.glob("*.npy")
    irf_cache_clear()
    read = information_reduction_factors(0.85, lam, 3.5, 2)
    assert irf_module._time_integrals.cache_info().misses == 0  # nothing integrated
    assert read.tobytes() == computed.tobytes() and 0.0 < read[2] < read[1] < read[0] < 0.85
    stored.write_bytes(stored.read_bytes()[:100])  # cut short
    irf_cache_clear()
    again = information_reduction_factors(0.85, lam, 3.5, 2)
    assert irf_module._time_integrals.cache_info().misses > 0
    assert again.tobytes() == computed.tobytes() and stored.stat().st_size > 1000


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((1.5, 0.0, 3.0, 1), r"pd must be in \[0.0, 1.0\]"),
        ((-0.1, 0.0, 3.0, 1), r"pd must be in \[0.0, 1.0\]"),
        ((float("nan"), 0.0, 3.0, 1), r"pd must be in"),
        ((0.9, -1.0, 3.0, 1), r"clutter_density must be finite and >= 0"),
        ((0.9, float("inf"), 3.0, 1), r"clutter_density must be finite and >= 0"),
        ((0.9, 0.1, 0.0, 1), r"gate_sigmas must be in \(0.0, 10.0\]"),
        ((0.9, 0.1, 12.0, 1), r"gate_sigmas must be in \(0.0, 10.0\]"),
        ((0.9, 0.1, 3.0, 0), r"dim: must be an integer in \[1, 3\]"),
        ((0.9, 0.1, 3.0, 2.0), r"dim: must be an integer in \[1, 3\]"),
        (("a", 0.1, 3.0, 1), r"pd must be a real number"),
    ],
)
def test_input_checks(args: tuple, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        information_reduction_factor(*args)


@pytest.mark.parametrize(("pd", "gate", "dim"), [(0.9, 3.5, 1), (0.85, 3.5, 2), (1.0, 2.0, 3)])
def test_table_is_the_exact_integral_between_its_nodes(pd: float, gate: float, dim: int) -> None:
    # Midway between the nodes (16 per decade) is where a cubic interpolant errs most; the
    # ends and everything outside the range (0 too) are the exact integral itself.
    lo, hi = IRF_TABLE_RANGE
    decades = math.log10(hi / lo)
    step = math.log(10.0) / 16
    mid = math.log(lo) + step * (np.arange(round(decades * 16)) + 0.5)
    lam = np.exp(mid[::5])
    got = information_reduction_factors(pd, lam, gate, dim)
    exact = np.array([information_reduction_factor(pd, float(v), gate, dim) for v in lam])
    assert got.shape == lam.shape
    assert np.max(np.abs(got - exact)) < IRF_TABLE_TOLERANCE
    assert np.max(np.abs(got - exact)) > 0.0  # interpolated, not the exact form
    outside = np.array([[0.0, 1e-9], [lo, 3e2]])
    want = [[information_reduction_factor(pd, float(v), gate, dim) for v in row] for row in outside]
    got_outside = information_reduction_factors(pd, outside, gate, dim)
    assert got_outside[0, 0] == want[0][0] and got_outside[0, 1] == want[0][1]
    assert got_outside[1, 1] == want[1][1]
    assert got_outside[1, 0] == pytest.approx(want[1][0], abs=1e-12)  # the table's first node
    assert float(information_reduction_factors(pd, 0.05, gate, dim)) == pytest.approx(
        information_reduction_factor(pd, 0.05, gate, dim), abs=IRF_TABLE_TOLERANCE
    )
    with pytest.raises(ValueError, match="clutter_density must be finite and >= 0"):
        information_reduction_factors(pd, [0.1, -1.0], gate, dim)


def _monte_carlo_fisher(
    pd: float, lam: float, gate: float, dim: int, n_samples: int, seed: int
) -> np.ndarray:
    """Per-sample scores of the PDA mixture likelihood (Niu et al. sec. II), by central
    differences of the full log-likelihood in a shift ``delta`` of the target's measurement mean
    (the gate stays where it is, centred on the true measurement)."""
    rng = np.random.default_rng(seed)
    volume = 2 * math.pi ** (dim / 2) / math.gamma(dim / 2) * gate**dim / dim
    p_gate = float(gammainc(dim / 2, gate * gate / 2))

    n_clutter = rng.poisson(lam * volume, n_samples)
    target = rng.standard_normal((n_samples, dim))
    has_target = (rng.random(n_samples) < pd) & (np.linalg.norm(target, axis=1) <= gate)
    m = n_clutter + has_target
    width = max(int(m.max()), 1)
    z = np.zeros((n_samples, width, dim))
    slot = np.arange(width)[None, :]
    clutter_slots = slot < n_clutter[:, None]
    n_total = int(n_clutter.sum())
    direction = rng.standard_normal((n_total, dim))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    radius = gate * rng.random(n_total) ** (1.0 / dim)  # uniform in the ball
    z[clutter_slots] = direction * radius[:, None]
    z[np.arange(n_samples)[has_target], n_clutter[has_target]] = target[has_target]
    occupied = slot < m[:, None]

    m_safe = np.maximum(m, 1)
    log_missed = math.log1p(-pd * p_gate) + poisson.logpmf(m, lam * volume) - m * math.log(volume)
    log_detected_const = (
        math.log(pd)
        + poisson.logpmf(m - 1, lam * volume)
        - (m - 1) * math.log(volume)
        - np.log(m_safe)
    )

    def log_likelihood(delta: np.ndarray) -> np.ndarray:
        d2 = np.sum((z - delta) ** 2, axis=2)
        dens = np.where(occupied, np.exp(-0.5 * d2) / (2 * math.pi) ** (dim / 2), 0.0)
        with np.errstate(divide="ignore"):
            log_detected = log_detected_const + np.log(dens.sum(axis=1))
        return np.logaddexp(log_missed, log_detected)

    h = 1e-5
    score = np.empty((n_samples, dim))
    for k in range(dim):
        e = np.zeros(dim)
        e[k] = h
        score[:, k] = (log_likelihood(e) - log_likelihood(-e)) / (2 * h)
    score[m == 0] = 0.0  # no measurement: the likelihood does not depend on the target
    return score


@pytest.mark.parametrize(
    ("pd", "lam", "gate", "dim"),
    [
        (1.0, 0.05, 4.0, 1),  # lambda V = 0.4 false alarms in the gate
        (0.9, 0.5, 4.0, 1),  # lambda V = 4
        (1.0, 0.01, 3.0, 2),  # lambda V = 0.28
        (0.9, 0.1, 3.0, 2),  # lambda V = 2.8
    ],
)
def test_monte_carlo_expected_fisher_information(
    pd: float, lam: float, gate: float, dim: int
) -> None:
    n_samples = 200_000
    score = _monte_carlo_fisher(pd, lam, gate, dim, n_samples, seed=14)
    per_sample = np.sum(score**2, axis=1) / dim
    q_mc = float(per_sample.mean())
    std_err = float(per_sample.std(ddof=1)) / math.sqrt(n_samples)
    q = information_reduction_factor(pd, lam, gate, dim)
    # Monte Carlo tolerance: 4 standard errors (std_err is 0.002-0.004 here).
    assert abs(q_mc - q) < 4 * std_err, (q, q_mc, std_err)
    if dim == 2:
        # Matrix scaling is scalar: E[s s^T] = q I (Niu et al.'s main result).
        fisher = score.T @ score / n_samples
        assert abs(fisher[0, 1]) < 4 * std_err
        assert abs(fisher[0, 0] - fisher[1, 1]) < 8 * std_err
