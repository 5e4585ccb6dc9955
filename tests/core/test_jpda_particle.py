"""The Monte Carlo JPDAF of particle tracks (activetrack.filters.jpda_particle, the tracker's
particle path) against what it must reduce to.

Figures asserted (seeded; measured values in the comments):
- the likelihood ratios are ``Pd sum_i w_i N(z_j; h(x_i), R) / lambda`` summed by hand
  (tracks of different particle counts, 1e-12), zero outside the gate;
- one track, no clutter (the tracker's floor on lambda, Pd 1 capped): beta_0 < 1e-9 and the
  update equals the single-target PF update on the same particles (1e-9);
- a linear sensor and Gaussian particles (200,000 per track): the betas equal the EKF JPDA's
  to Monte Carlo tolerance for two well-separated tracks and for two tracks sharing both
  detections, and the updated particle mean and covariance equal the JPDA-EKF's (exact for a
  linear-Gaussian sensor) to a few thousandths of a standard deviation;
- a particle filter whose ``update_pda`` computes its own likelihoods gives the tracks the
  built-in one gets with the tracker's (1e-9);
- (the closed loop on (a), the particle tracker's GOSPA no worse than the JPDA-EKF's, is in
  test_multitarget_reproduction_a.py, on the runs of (a)'s reproduction).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from linear_sensor import LinearPositionSensor

from activetrack.filters.clutter_likelihood import effective_clutter_density, effective_pd
from activetrack.filters.jpda import (
    gate_probability,
    jpda_association,
    jpda_probabilities,
    jpda_update,
)
from activetrack.filters.jpda_particle import particle_likelihoods
from activetrack.filters.measurement import Measurement
from activetrack.filters.particle import ParticleFilter
from activetrack.filters.registry import register_filter, unregister_filter
from activetrack.models.motion import NearlyConstantVelocity
from activetrack.models.sensors import BearingSensor

MODEL = NearlyConstantVelocity(q=0.1)
SENSOR_PV = np.array([-2000.0, 0.0, -1500.0, 0.0])
BEARING = BearingSensor(sigma=0.01, pd=0.9)
LINEAR = LinearPositionSensor(sigma=10.0, pd=0.9)
GAMMA = 16.0


def particle_filter(X, w=None, **options):
    options.setdefault("resample", "ess")
    options.setdefault("ess_threshold", 0.0)  # never resample: the moments are the weights'
    return ParticleFilter(MODEL, particles=X, weights=w, t0=1.0, **options)


def cloud(mean, std, count, seed):
    """Particles around ``mean`` with uneven weights."""
    rng = np.random.default_rng(seed)
    X = np.asarray(mean) + rng.normal(size=(count, 4)) * std
    w = rng.uniform(0.5, 1.5, count)
    return X, w / w.sum()


def bearing_density(z, X):
    """N(z; atan2(dy, dx), sigma^2) per particle, by hand (residual wrapped)."""
    b = np.arctan2(X[:, 2] - SENSOR_PV[2], X[:, 0] - SENSOR_PV[0])
    nu = np.angle(np.exp(1j * (z - b)))
    return np.exp(-0.5 * (nu / 0.01) ** 2) / (math.sqrt(2.0 * math.pi) * 0.01)


def detections(sensor, Z, s=SENSOR_PV):
    return [Measurement(sensor, s, z, 1.0, "s1") for z in Z]


def ratios(filters, Z, sensor, gated, lam, pd):
    return particle_likelihoods(filters, Z, sensor, SENSOR_PV, MODEL, gated=gated).ratios(pd, lam)


def test_likelihood_ratios_are_the_weighted_particle_sums():
    tracks = [cloud([0.0, 10.0, 0.0, 5.0], [30.0, 1.0, 30.0, 1.0], 50, 1)]
    tracks.append(cloud([200.0, 0.0, -100.0, 0.0], [30.0, 1.0, 30.0, 1.0], 80, 2))
    filters = [particle_filter(X, w) for X, w in tracks]
    Z = np.array([[0.645], [0.61], [0.58]])
    gated = np.array([[True, True, False], [False, True, True]])
    lam, pd = 4.0, np.array([0.9, 0.7])
    found = particle_likelihoods(filters, Z, BEARING, SENSOR_PV, MODEL, gated=gated)
    densities = [[bearing_density(z[0], X) for z in Z] for X, _ in tracks]
    expected = np.array([[w @ g for g in densities[t]] for t, (_, w) in enumerate(tracks)])
    assert (expected > 1e-9).all()  # every pair has mass: the zeros are the gate's
    np.testing.assert_allclose(np.exp(found.log_p), np.where(gated, expected, 0.0), rtol=1e-12)
    np.testing.assert_allclose(
        found.ratios(pd, lam), np.where(gated, pd[:, None] * expected / lam, 0.0), rtol=1e-12
    )
    # the per-particle terms kept for the update: log g less the constant, gated pairs only
    c = -0.5 * math.log(2.0 * math.pi * 0.01**2)
    for t, j in np.argwhere(gated):
        np.testing.assert_allclose(np.exp(found.ell[t][j] + c), densities[t][j], rtol=1e-12)
    assert [[e is None for e in row] for row in found.ell] == (~gated).tolist()


def test_likelihoods_refuse_a_gate_of_the_wrong_shape():
    f = particle_filter(*cloud([0.0, 0.0, 0.0, 0.0], 10.0, 20, 3))
    with pytest.raises(ValueError, match="gated must have shape"):
        particle_likelihoods([f], [[0.6]], BEARING, SENSOR_PV, MODEL, gated=np.ones((2, 1), bool))


def test_update_refuses_likelihoods_of_the_wrong_shape():
    f = particle_filter(*cloud([0.0, 0.0, 0.0, 0.0], 10.0, 20, 3))
    z = detections(BEARING, [[0.6]])
    with pytest.raises(ValueError, match="one entry per detection"):
        f.update_pda(z, [0.5, 0.5], log_likelihoods=[])
    with pytest.raises(ValueError, match=r"log_likelihoods\[0\] must have shape \(20,\)"):
        f.update_pda(z, [0.5, 0.5], log_likelihoods=[np.zeros(3)])


def test_one_track_without_clutter_is_the_single_target_update():
    X, w = cloud([0.0, 10.0, 0.0, 5.0], [30.0, 1.0, 30.0, 1.0], 400, 4)
    z = np.array([[0.64]])
    pd, lam = effective_pd(1.0), effective_clutter_density(0.0)
    jpda_pf, plain = particle_filter(X, w), particle_filter(X, w)
    found = particle_likelihoods(
        [jpda_pf], z, BEARING, SENSOR_PV, MODEL, gated=np.ones((1, 1), bool)
    )
    beta = jpda_probabilities(found.ratios(pd, lam), pd, gate_probability(GAMMA, 1))
    assert beta[0, 0] < 1e-9
    jpda_pf.update_pda(detections(BEARING, z), beta[0], log_likelihoods=found.ell[0])
    plain.update(detections(BEARING, z))
    np.testing.assert_allclose(jpda_pf.weights, plain.weights, rtol=1e-9, atol=0)
    assert np.abs(plain.weights - w).max() > 0.5 * w.max()  # the update moved the weights
    again = particle_filter(X, w)  # the likelihoods computed by the filter itself: same weights
    again.update_pda(detections(BEARING, z), beta[0])
    np.testing.assert_allclose(again.weights, jpda_pf.weights, rtol=1e-12, atol=0)


def gaussian_tracks(means, P, count, seed):
    rng = np.random.default_rng(seed)
    L = np.linalg.cholesky(P)
    return [particle_filter(m + rng.standard_normal((count, 4)) @ L.T) for m in means]


P_TRACK = np.diag([400.0, 4.0, 400.0, 4.0])


@pytest.mark.parametrize(
    ("means", "Z"),
    [
        # well separated, one detection each and a false alarm near the first
        (
            [[0.0, 0.0, 0.0, 0.0], [500.0, 0.0, 400.0, 0.0]],
            [[2005.0, 1490.0], [2495.0, 1910.0], [1980.0, 1530.0]],
        ),
        # 30 m apart: both detections gated by both tracks
        ([[0.0, 0.0, 0.0, 0.0], [30.0, 0.0, 10.0, 0.0]], [[2012.0, 1502.0], [2022.0, 1508.0]]),
    ],
)
def test_betas_equal_the_ekf_jpda_on_a_linear_sensor(means, Z):
    means, Z = np.array(means), np.array(Z)
    filters = gaussian_tracks(means, P_TRACK, 200_000, 5)
    lam = 1e-5
    a = jpda_association(
        means,
        np.stack([P_TRACK, P_TRACK]),
        Z,
        LINEAR,
        SENSOR_PV,
        MODEL,
        clutter_density=lam,
        gamma=GAMMA,
    )
    l = ratios(filters, Z, LINEAR, a.gated, lam, LINEAR.pd)
    np.testing.assert_allclose(l, a.likelihood_ratios, rtol=0.02)  # measured 0.7 % at most
    beta = jpda_probabilities(l, LINEAR.pd, gate_probability(GAMMA, 2))
    np.testing.assert_allclose(beta, a.beta, atol=0.005)  # measured 0.0011 at most
    assert a.beta[:, 1:].max() > 0.3 and (a.beta[:, 1:] > 0.0).sum() >= 3  # non-trivial


def test_updated_moments_equal_the_jpda_ekf_on_a_linear_sensor():
    """For a linear-Gaussian sensor the association mixture's mean and covariance are the PDA's
    (Bar-Shalom, Daum & Huang 2009, eq. 23-27), so the MC-JPDAF must reproduce the JPDA-EKF."""
    means = np.array([[0.0, 0.0, 0.0, 0.0], [30.0, 0.0, 10.0, 0.0]])
    Z = np.array([[2012.0, 1502.0], [2022.0, 1508.0], [1990.0, 1480.0]])
    filters = gaussian_tracks(means, P_TRACK, 200_000, 6)
    # the particles' own moments as the EKF's prior: the comparison is of the updates alone
    X0 = np.array([f.mean for f in filters])
    P0 = np.array([f.cov for f in filters])
    lam = 1e-5
    ekf = jpda_update(X0, P0, Z, LINEAR, SENSOR_PV, MODEL, clutter_density=lam, gamma=GAMMA)
    l = ratios(filters, Z, LINEAR, ekf.gated, lam, LINEAR.pd)
    beta = jpda_probabilities(l, LINEAR.pd, gate_probability(GAMMA, 2))
    for t, f in enumerate(filters):
        f.update_pda(detections(LINEAR, Z), beta[t])
        std = np.sqrt(np.diag(ekf.covs[t]))
        # measured: means within 0.0045 std, stds within 0.21 %
        assert (np.abs(f.mean - ekf.means[t]) / std < 0.01).all()
        np.testing.assert_allclose(np.sqrt(np.diag(f.cov)), std, rtol=0.01)
        assert np.linalg.norm(f.mean - X0[t]) > 3.0  # the update moved the track


class _PlainUpdatePF(ParticleFilter):
    """A particle filter whose ``update_pda`` takes no precomputed likelihoods (as a plugin's
    may not): the tracker must compute nothing differently for it."""

    def update_pda(self, measurements, beta):
        return super().update_pda(measurements, beta)


def test_reused_likelihoods_give_the_track_a_filter_computing_its_own_gets():
    from test_tracker import make_scenario, range_bearing, run, simulate

    def plain(model, x0, P0, config, rng, t0=0.0):
        return _PlainUpdatePF(model, x0, P0, n_particles=config.particles, rng=rng, t0=t0)

    targets = [
        {"id": "a", "mean": [100.0, 8.0, 200.0, -5.0], "q": 0.5},
        {"id": "b", "mean": [160.0, 6.0, 260.0, -7.0], "q": 0.5},
    ]
    register_filter("pf_plain_update", plain, particle_based=True)
    try:
        sc = make_scenario(
            targets, [range_bearing(pd=0.9, clutter_density=3e-4)], steps=12, filter="pf"
        )
        sc = sc.model_copy(update={"tracker": sc.tracker.model_copy(update={"particles": 500})})
        other = sc.model_copy(
            update={"tracker": sc.tracker.model_copy(update={"filter": "pf_plain_update"})}
        )
        _, scans = simulate(sc, 12, np.random.default_rng(3))
        _, reused = run(sc, scans, seed=7)
        _, computed = run(other, scans, seed=7)
    finally:
        unregister_filter("pf_plain_update")
    shared = 0
    for a, b in zip(reused[1:], computed[1:], strict=True):
        assert [t.track_id for t in a.tracks] == [t.track_id for t in b.tracks]
        for s, t in zip(a.tracks, b.tracks, strict=True):
            np.testing.assert_allclose(s.mean, t.mean, rtol=1e-9, atol=1e-9)
        shared += a.detections > 0
    assert shared >= 10  # the tracks were updated, not just predicted
