"""Tests of the SIR particle filter (activetrack.filters.particle) and its resampling."""

import math

import numpy as np
import pytest
from filterpy.monte_carlo import systematic_resample as filterpy_systematic_resample
from linear_sensor import LinearPositionSensor

from activetrack.angles import wrap_angle
from activetrack.filters import (
    ExtendedKalmanFilter,
    FilterCollapseError,
    Measurement,
    ParticleFilter,
    effective_sample_size,
    roughen,
    systematic_indices,
)
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


X0 = np.array([100.0, 2.0, -50.0, 1.0])
P0 = np.diag([100.0, 4.0, 100.0, 4.0])
ORIGIN = np.zeros(4)


def linear_scenario(n_steps=5, seed=1):
    model = NearlyConstantVelocity(1.0)
    sensor = LinearPositionSensor(20.0)
    rng = np.random.default_rng(seed)
    x = X0 + np.linalg.cholesky(P0) @ rng.standard_normal(4)
    meas = []
    for k in range(1, n_steps + 1):
        x = model.sample(x, 1.0, rng)
        meas.append(Measurement(sensor, ORIGIN, sensor.sample(x, ORIGIN, rng), float(k)))
    return model, meas


def test_systematic_resampling_matches_filterpy():
    for seed in range(60):
        rng = np.random.default_rng(seed)
        n = (1, 2, 7, 100, 3000)[seed % 5]
        w = rng.random(n) ** (1 + seed % 6 * 4)  # from flat to very skewed
        w /= w.sum()
        # filterpy draws its offset from numpy's legacy global generator.
        np.random.seed(seed)  # noqa: NPY002
        expected = filterpy_systematic_resample(w)
        np.random.seed(seed)  # noqa: NPY002
        u = np.random.random()  # noqa: NPY002
        np.testing.assert_array_equal(systematic_indices(w, u), expected)
    # Copies per particle are floor(N w) or ceil(N w) (the defining property).
    w = np.random.default_rng(0).dirichlet(np.ones(50))
    counts = np.bincount(systematic_indices(w, 0.37), minlength=50)
    assert np.all(counts >= np.floor(50 * w)) and np.all(counts <= np.ceil(50 * w))
    assert counts.sum() == 50


def test_pf_matches_kalman_filter_on_linear_gaussian_model():
    """NCV + linear position sensor: the PF estimates the KF's posterior.

    Tolerance: for SIR the Monte Carlo error of the mean is ~ c P / N with c ~ N / ESS for
    an importance-sampling step plus what resampling carried over from earlier steps. Here
    ESS >= 0.7 N every step, and over 60 seeds c measured 1.9-2.8 per component; we allow
    c = 4 at 5 sigma: |mean_pf - mean_kf|_i <= 5 sqrt(4 P_ii / N). The sample covariance then
    has relative error std ~ sqrt(2 c / N) = 0.028: eigenvalues of P_kf^-1/2 P_pf P_kf^-1/2
    within 5 x 0.028 = 0.14 of 1 (measured max deviation over 60 seeds 0.07).
    """
    model, meas = linear_scenario()
    N = 10_000
    kf = ExtendedKalmanFilter(model, X0, P0)
    pf = ParticleFilter(model, X0, P0, n_particles=N, rng=7)
    log_lik_kf = log_lik_pf = 0.0
    for m in meas:
        log_lik_kf += kf.step(m.time, [m]).log_likelihood
        info = pf.step(m.time, [m])
        log_lik_pf += info.log_likelihood
        assert info.ess > 0.7 * N and info.resampled
    P = kf.cov
    tol = 5.0 * np.sqrt(4.0 * np.diag(P) / N)
    np.testing.assert_array_less(np.abs(pf.mean - kf.mean), tol)
    L = np.linalg.cholesky(P)
    whitened = np.linalg.solve(L, np.linalg.solve(L, pf.cov).T)
    np.testing.assert_array_less(np.abs(np.linalg.eigvalsh(whitened) - 1.0), 0.14)
    # log p(Z) estimate: error std ~ sqrt(steps * c / N) = 0.03; allow 5 sigma.
    assert log_lik_pf == pytest.approx(log_lik_kf, abs=0.15)
    # The tolerances discriminate: the prediction without measurements fails both checks.
    F, Q = model.transition_matrix(1.0), model.process_noise(1.0)
    x_pred, P_pred = X0, P0
    for _ in meas:
        x_pred, P_pred = F @ x_pred, F @ P_pred @ F.T + Q
    assert np.any(np.abs(x_pred - kf.mean) > 5 * tol)
    whitened = np.linalg.solve(L, np.linalg.solve(L, P_pred).T)
    assert np.max(np.abs(np.linalg.eigvalsh(whitened) - 1.0)) > 10 * 0.14


def test_seeded_runs_are_reproducible():
    model, meas = linear_scenario(3)
    a = ParticleFilter(model, X0, P0, n_particles=1000, rng=3)
    b = ParticleFilter(model, X0, P0, n_particles=1000, rng=np.random.default_rng(3))
    for m in meas:
        a.step(m.time, [m])
        b.step(m.time, [m])
    np.testing.assert_array_equal(a.particles, b.particles)


@pytest.mark.parametrize(
    ("fast", "generic", "z"),
    [
        (BearingSensor(0.05), GenericBearing(0.05), [math.pi - 0.01]),
        (BearingSensor(0.05), GenericBearing(0.05), [-math.pi + 0.02]),
        (RangeBearingSensor(20.0, 0.05), GenericRangeBearing(20.0, 0.05), [1000.0, 3.13]),
    ],
)
@pytest.mark.parametrize("min_range", ["ignore", "negative"])
def test_inline_likelihood_equals_generic_and_wraps(fast, generic, z, min_range):
    """Target west of the sensor: particle bearings straddle the +-pi cut."""
    model = NearlyConstantVelocity(0.1)
    x0 = np.array([-1000.0, 0.0, 0.0, 0.0])
    P = np.diag([100.0**2, 1.0, 100.0**2, 1.0])
    opts = dict(n_particles=5000, resample="ess", ess_threshold=0.0, min_range=min_range)
    a = ParticleFilter(model, x0, P, rng=11, **opts)
    b = ParticleFilter(model, particles=a.particles, rng=11, **opts)
    ia = a.update([Measurement(fast, ORIGIN, z, 0.0)])
    ib = b.update([Measurement(generic, ORIGIN, z, 0.0)])
    np.testing.assert_allclose(a.weights, b.weights, rtol=1e-9, atol=1e-300)
    assert ia.log_likelihood == pytest.approx(ib.log_likelihood, abs=1e-9)
    # Independent check of the wrapped-residual weights for the bearing entry.
    bearing = np.arctan2(a.particles[:, 2], a.particles[:, 0])
    e = wrap_angle(z[-1] - bearing) / 0.05
    if isinstance(fast, RangeBearingSensor):
        e_r = (z[0] - np.hypot(a.particles[:, 0], a.particles[:, 2])) / 20.0
        logw = -0.5 * (e**2 + e_r**2)
    else:
        logw = -0.5 * e**2
    w = np.exp(logw - logw.max())
    np.testing.assert_allclose(a.weights, w / w.sum(), rtol=1e-9, atol=1e-300)
    # Both sides of the cut keep weight: the posterior is not split by a 2 pi jump.
    assert a.weights[a.particles[:, 2] > 0].sum() > 0.05
    assert a.weights[a.particles[:, 2] < 0].sum() > 0.05


@pytest.mark.parametrize(
    ("fast", "generic", "z"),
    [
        (BearingSensor(0.8), GenericBearing(0.8), [2.5]),
        (RangeBearingSensor(50.0, 0.8), GenericRangeBearing(50.0, 0.8), [100.0, -3.0]),
    ],
)
def test_inline_likelihood_equals_generic_all_around_the_sensor(fast, generic, z):
    """Particles on every side of the sensor, so residuals reach +-pi (behind the sensor)."""
    model = NearlyConstantVelocity(0.1)
    P = np.diag([100.0**2, 1.0, 100.0**2, 1.0])
    opts = dict(n_particles=5000, resample="ess", ess_threshold=0.0)
    a = ParticleFilter(model, np.zeros(4), P, rng=12, **opts)
    b = ParticleFilter(model, particles=a.particles, **opts)
    a.update([Measurement(fast, ORIGIN, z, 0.0)])
    b.update([Measurement(generic, ORIGIN, z, 0.0)])
    np.testing.assert_allclose(a.weights, b.weights, rtol=1e-9, atol=0)
    e = wrap_angle(z[-1] - np.arctan2(a.particles[:, 2], a.particles[:, 0]))
    assert np.max(np.abs(e)) > 3.1 and np.mean(np.abs(e) > np.pi / 2) > 0.2


def test_missed_detection_ignore_mode_changes_nothing():
    model = NearlyConstantVelocity(0.1)
    sensor = BearingSensor(0.01, pd=0.9, r_min=150.0)
    pf = ParticleFilter(model, X0, P0, n_particles=2000, rng=4, min_range="ignore")
    before_x, before_w = pf.particles.copy(), pf.weights.copy()
    info = pf.update([Measurement(sensor, ORIGIN, None, 0.0, "a")] * 3)
    np.testing.assert_array_equal(pf.particles, before_x)
    np.testing.assert_array_equal(pf.weights, before_w)
    assert (info.n_missed, info.n_detections, info.resampled) == (3, 0, False)
    assert info.ess == pytest.approx(2000.0) and info.log_likelihood == 0.0


def near_sensor_filter(min_range, pd, n=20_000, **opts):
    """Prior straddling a sensor's r_min = 115 m (the target ~ 112 m away, std 10 m)."""
    model = NearlyConstantVelocity(0.1)
    sensor = BearingSensor(0.01, pd=pd, r_min=115.0)
    pf = ParticleFilter(model, X0, P0, n_particles=n, rng=5, min_range=min_range, **opts)
    inside = np.hypot(pf.particles[:, 0], pf.particles[:, 2]) < sensor.r_min
    return pf, sensor, inside


def test_missed_detection_negative_mode_moves_mass_inside_r_min():
    """Weights 1 - pd I_r(x): inside r_min (I_r = 0) keep 1, outside get 1 - pd, so the
    posterior mass inside is p / (p + (1 - pd)(1 - p)) for prior mass p."""
    pd = 0.9
    pf, sensor, inside = near_sensor_filter("negative", pd, resample="ess", ess_threshold=0.0)
    p = inside.mean()
    assert 0.1 < p < 0.9  # the prior really straddles r_min
    info = pf.update([Measurement(sensor, ORIGIN, None, 0.0)])
    expected = p / (p + (1.0 - pd) * (1.0 - p))
    assert pf.weights[inside].sum() == pytest.approx(expected, abs=1e-12)
    assert info.log_likelihood == pytest.approx(math.log(p + (1 - pd) * (1 - p)), abs=1e-12)
    assert not info.resampled and 1.0 <= info.ess <= pf.n_particles
    # With resampling the particle cloud itself moves inside r_min.
    pf2, _, _ = near_sensor_filter("negative", pd)
    pf2.update([Measurement(sensor, ORIGIN, None, 0.0)])
    frac_after = np.mean(np.hypot(pf2.particles[:, 0], pf2.particles[:, 2]) < 115.0)
    assert frac_after == pytest.approx(expected, abs=0.01)  # N = 2e4: binomial std 0.003
    # Ignore mode on the same prior: unchanged.
    pf3, _, inside3 = near_sensor_filter("ignore", pd)
    pf3.update([Measurement(sensor, ORIGIN, None, 0.0)])
    assert np.mean(np.hypot(pf3.particles[:, 0], pf3.particles[:, 2]) < 115.0) == inside3.mean()


def test_negative_mode_detection_excludes_particles_inside_r_min():
    pf, sensor, inside = near_sensor_filter("negative", 0.9, resample="ess", ess_threshold=0.0)
    z = [math.atan2(X0[2], X0[0])]
    pf.update([Measurement(sensor, ORIGIN, z, 0.0)])
    assert pf.weights[inside].sum() == 0.0 and pf.weights[~inside].sum() == pytest.approx(1.0)
    ignore, _, inside_i = near_sensor_filter("ignore", 0.9, resample="ess", ess_threshold=0.0)
    ignore.update([Measurement(sensor, ORIGIN, z, 0.0)])
    assert ignore.weights[inside_i].sum() > 0.1  # ignore mode does not use the range limit


def test_weight_collapse_reset_or_raise():
    # pd = 1 and every particle in range: "no detection" has probability 0 under the model.
    model = NearlyConstantVelocity(0.1)
    sensor = BearingSensor(0.01, pd=1.0)
    m = Measurement(sensor, ORIGIN, None, 0.0, "s1")
    pf = ParticleFilter(model, X0, P0, n_particles=500, rng=6, min_range="negative")
    before = pf.particles.copy()
    info = pf.update([m])
    assert info.collapsed and "collapsed" in info.message and "s1" in info.message
    np.testing.assert_array_equal(pf.particles, before)
    assert pf.ess == pytest.approx(500.0)
    strict = ParticleFilter(
        model, X0, P0, n_particles=500, rng=6, min_range="negative", on_collapse="raise"
    )
    with pytest.raises(FilterCollapseError, match="collapsed"):
        strict.update([m])


def test_log_weights_survive_extreme_likelihoods():
    """sigma = 1e-7 rad: every naive likelihood exp(-0.5 e^2 / sigma^2) underflows to 0."""
    model = NearlyConstantVelocity(0.1)
    sensor = BearingSensor(1e-7)
    pf = ParticleFilter(model, X0, P0, n_particles=3000, rng=8, resample="ess", ess_threshold=0)
    bearings = np.arctan2(pf.particles[:, 2], pf.particles[:, 0])
    z = [bearings.max() + 0.001]  # beyond every particle by >= 1e4 sigma
    assert np.all(np.exp(-0.5 * ((z[0] - bearings) / 1e-7) ** 2) == 0.0)
    info = pf.update([Measurement(sensor, ORIGIN, z, 0.0)])
    assert not info.collapsed and np.all(np.isfinite(pf.weights))
    assert pf.weights.sum() == pytest.approx(1.0)
    assert np.argmax(pf.weights) == np.argmin(np.abs(bearings - z[0]))
    assert 1.0 <= info.ess < 2.0


def test_ess_reported_and_ess_triggered_resampling():
    model, meas = linear_scenario(8, seed=2)
    N = 2000
    pf = ParticleFilter(model, X0, P0, n_particles=N, rng=9, resample="ess", ess_threshold=0.8)
    seen = set()
    for m in meas:
        pf.predict(m.time)
        w_prior = pf.weights.copy()
        info = pf.update([m])
        assert 1.0 <= info.ess <= N
        assert info.resampled == (info.ess < 0.8 * N)
        seen.add(info.resampled)
        if info.resampled:
            assert pf.ess == pytest.approx(N)
        else:
            assert info.ess == pytest.approx(effective_sample_size(pf.weights), rel=1e-12)
            assert pf.ess < N and not np.array_equal(pf.weights, w_prior)
    assert seen == {True, False}  # both branches were exercised


def test_roughening_jitter_scale():
    """Gordon et al.: jitter std K E_i N^(-1/d) per component, E_i the particle spread."""
    rng = np.random.default_rng(10)
    N, d, K = 20_000, 4, 0.2
    X = rng.uniform(0.0, 1.0, (N, d)) * [10.0, 1.0, 50.0, 2.0]
    Y = X.copy()
    roughen(Y, K, rng)
    expected = K * (X.max(0) - X.min(0)) * N ** (-1.0 / d)
    np.testing.assert_allclose((Y - X).std(axis=0), expected, rtol=0.03)  # std rel err 0.5 %
    Z = X.copy()
    roughen(Z, 0.0, rng)
    np.testing.assert_array_equal(Z, X)
    # In the filter: after resampling, roughening leaves no duplicated particles.
    model, meas = linear_scenario(1)
    plain = ParticleFilter(model, X0, P0, n_particles=2000, rng=1)
    rough = ParticleFilter(model, X0, P0, n_particles=2000, rng=1, roughening=0.2)
    plain.step(1.0, meas[:1])
    rough.step(1.0, meas[:1])
    assert len(np.unique(plain.particles[:, 0])) < 2000
    assert len(np.unique(rough.particles[:, 0])) == 2000


def test_initialise_from_particles():
    model = NearlyConstantVelocity(0.1)
    rng = np.random.default_rng(12)
    X = X0 + rng.standard_normal((400, 4))
    w = rng.random(400)
    pf = ParticleFilter.from_particles(model, X, w, t0=3.0, rng=0)
    wn = w / w.sum()
    np.testing.assert_allclose(pf.mean, wn @ X, rtol=1e-12)
    D = X - wn @ X
    np.testing.assert_allclose(pf.cov, (D.T * wn) @ D, rtol=1e-12)
    assert pf.time == 3.0 and pf.n_particles == 400
    assert pf.ess == pytest.approx(1.0 / np.sum(wn**2))
    X[0, 0] = 1e9  # the filter holds its own copy
    assert pf.particles[0, 0] != 1e9
    with pytest.raises(ValueError):
        pf.particles[0, 0] = 0.0  # read-only view


@pytest.mark.parametrize(
    ("model", "x0", "P"),
    [
        (NearlyConstantVelocityDiscrete(0.05, 0.05), X0, P0),
        (ConstantTurn(0.01, 0.05), X0, P0),
        (
            CircularMotion(0.001, 0.05),
            np.array([0.5, 100.0, -50.0, 0.01, 2.0]),
            np.diag([0.05, 100.0, 100.0, 0.005**2, 0.2**2]),
        ),
        (
            CircularMotionKnownOmega(0.01, 0.05),
            np.array([0.5, 100.0, -50.0, 2.0]),
            np.diag([0.05, 100.0, 100.0, 0.2**2]),
        ),
    ],
)
@pytest.mark.parametrize(
    "sensor",
    [
        BearingSensor(0.01),
        RangeBearingSensor(5.0, 0.02),
        RangeRateBearingSensor(5.0, 0.2, 0.02),
        AmbiguousBearingSensor(0.01),
    ],
)
def test_every_model_and_sensor(model, x0, P, sensor):
    rng = np.random.default_rng(13)
    sensors = [np.array([0.0, 0.0, 300.0, 0.0]), np.array([300.0, 0.0, 0.0, 0.0])]
    pf = ParticleFilter(model, x0, P, n_particles=3000, rng=14)
    x = x0.copy()
    for k in range(1, 6):
        x = model.sample(x, 1.0, rng)
        pv = model.kinematics(x)
        ms = [Measurement(sensor, s, sensor.sample(pv, s, rng), float(k)) for s in sensors]
        info = pf.step(float(k), ms)
        assert 1.0 <= info.ess <= 3000 and not info.collapsed
    assert pf.particles.shape == (3000, model.dim)
    assert np.linalg.eigvalsh(pf.cov)[0] >= 0.0
    # The posterior position spread covers the truth.
    est, truth = model.kinematics(pf.particles), model.kinematics(x)
    for i in (0, 2):
        lo, hi = np.quantile(est[:, i], [0.0005, 0.9995])
        assert lo <= truth[i] <= hi


def test_bad_inputs_raise_value_error_naming_the_argument():
    model = NearlyConstantVelocity(0.1)
    for bad in (0, -3, 2.5, True, "100"):
        with pytest.raises(ValueError, match="n_particles"):
            ParticleFilter(model, X0, P0, n_particles=bad)
    cases = [
        (dict(ess_threshold=1.5), "ess_threshold"),
        (dict(ess_threshold=math.nan), "ess_threshold"),
        (dict(roughening=-0.1), "roughening"),
        (dict(resample="sometimes"), "resample"),
        (dict(min_range="clip"), "min_range"),
        (dict(on_collapse="ignore"), "on_collapse"),
        (dict(t0=math.inf), "t0"),
    ]
    for kwargs, name in cases:
        with pytest.raises(ValueError, match=name):
            ParticleFilter(model, X0, P0, n_particles=10, **kwargs)
    with pytest.raises(ValueError, match="P0"):
        ParticleFilter(model, X0, -P0, n_particles=10)
    with pytest.raises(ValueError, match="x0"):
        ParticleFilter(model, X0[:2], P0, n_particles=10)
    X = np.zeros((5, 4))
    with pytest.raises(ValueError, match="particles"):
        ParticleFilter(model, particles=np.full((5, 4), math.nan))
    with pytest.raises(ValueError, match="particles"):
        ParticleFilter(model, particles=np.zeros((5, 3)))
    with pytest.raises(ValueError, match="weights"):
        ParticleFilter(model, particles=X, weights=[1, 1, 1, 1, -1])
    with pytest.raises(ValueError, match="weights"):
        ParticleFilter(model, particles=X, weights=np.zeros(5))
    with pytest.raises(ValueError, match="n_particles"):
        ParticleFilter(model, particles=X, n_particles=6)
    pf = ParticleFilter(model, particles=X, t0=1.0)
    with pytest.raises(ValueError, match="t"):
        pf.predict(0.5)
    with pytest.raises(ValueError, match="measurements"):
        pf.update([Measurement(BearingSensor(0.1), ORIGIN, [0.0], 2.0)])
    with pytest.raises(ValueError, match="z"):
        Measurement(BearingSensor(0.1), ORIGIN, [math.inf], 1.0)
    # Default size is Hernandez's 10,000.
    assert ParticleFilter(model, X0, P0, rng=0).n_particles == 10_000
