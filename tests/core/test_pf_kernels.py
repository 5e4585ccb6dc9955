"""The compiled kernels (activetrack.kernels) against their numpy references.

Every kernel draws the same random numbers from the same generator as its reference and does
the same floating-point operations in the same order, so the tests ask for identical bits
(``assert_array_equal``), which is stronger than the 1e-12 the issue asks for; no draw order
changes, so no statistical comparison is needed. Each test runs both paths in one process with
``set_kernels`` and equal seeds. The EKF kernels (compiled mode only) agree to round-off: their
loop-order sums differ from numpy's BLAS products in the last bits, so those tests ask 1e-12.
"""

import math

import numpy as np
import pytest
from linear_sensor import LinearPositionSensor

from activetrack import kernels
from activetrack.filters import (
    ExtendedKalmanFilter,
    Measurement,
    ParticleFilter,
    systematic_indices,
)
from activetrack.models.motion import (
    CircularMotion,
    ConstantTurn,
    NearlyConstantVelocity,
    NearlyConstantVelocityDiscrete,
)
from activetrack.models.sensors import AmbiguousBearingSensor, BearingSensor, RangeBearingSensor

pytest.importorskip("numba")
# A particle placed on the sensor divides 0 by 0 on the numpy path (NaN on purpose).
pytestmark = pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")

SENSOR_PV = np.array([1800.0, -40.0, 2000.0, -40.0])


@pytest.fixture(autouse=True)
def _restore_mode():
    yield
    kernels.set_kernels(None)


def both(fn):
    """``fn()`` on the numpy path and on the compiled path."""
    kernels.set_kernels("numpy")
    ref = fn()
    kernels.set_kernels("compiled")
    assert kernels.compiled_enabled()
    return ref, fn()


def particles(n=5000, seed=3):
    rng = np.random.default_rng(seed)
    return np.array([0.0, 8.0, 0.0, 6.0]) + rng.standard_normal((n, 4)) * [300.0, 1.0, 300.0, 1.0]


@pytest.mark.parametrize(
    "model",
    [
        NearlyConstantVelocity(0.01),
        NearlyConstantVelocityDiscrete(0.3, 0.5),
        ConstantTurn(0.05, 0.1),
    ],
)
def test_sampling_draws_the_same_normals_and_gives_the_same_bits(model):
    X = particles()

    def sample():
        rng = np.random.default_rng(11)
        return model.sample(X, 5.0, rng), rng.random()  # and the generator's state after

    (ref, after_ref), (out, after) = both(sample)
    np.testing.assert_array_equal(out, ref)
    assert after == after_ref
    # The reference is x F^T + w L^T: check it against the plain matmul to round-off.
    from activetrack.models._common import noise_factor

    W = np.random.default_rng(11).standard_normal(X.shape)
    L = noise_factor(model.process_noise(5.0))
    np.testing.assert_allclose(ref, X @ model.transition_matrix(5.0).T + W @ L.T, rtol=1e-12)


@pytest.mark.parametrize("cv", [True, False])
def test_pcg64_route_draws_numpys_normals_and_leaves_its_state(cv):
    """The compiled PCG64 stream (16 LCG chains, numpy's ziggurat, a 2,048-output buffer
    refilled inside rows) gives ``standard_normal``'s bits and state for many seeds and sizes:
    rows that straddle a refill, rejections in the tail and the wedge, a 32-bit half kept
    buffered by an earlier ``integers`` draw."""
    from activetrack.kernels import particle

    F = NearlyConstantVelocity(0.01).transition_matrix(5.0)
    L = np.linalg.cholesky(NearlyConstantVelocity(0.01).process_noise(5.0))
    if not cv:
        F, L = F + 0.01, L + np.tril(np.full((4, 4), 0.02))
    draws = 0
    for seed in range(12):
        for n in (1, 3, 511, 512, 513, 5000):
            X = particles(n, seed)
            ours, ref = np.random.default_rng([seed, n]), np.random.default_rng([seed, n])
            if seed % 2:
                ours.integers(0, 2**32, dtype=np.uint32)
                ref.integers(0, 2**32, dtype=np.uint32)
            out, finite = particle.gaussian_sample(X, F, L, cv, ours)
            W = ref.standard_normal((n, 4))
            want = np.empty_like(X)
            rows = particle._cv_rows_from_normals if cv else particle._full_rows_from_normals
            rows(W, X, F, L, want)
            np.testing.assert_array_equal(out, want)
            assert finite
            assert ours.bit_generator.state == ref.bit_generator.state
            assert ours.random() == ref.random()
            draws += 4 * n
    assert draws > 300_000  # about 4,700 rejections (1.5 %), about 80 in layer 0's tail


@pytest.mark.parametrize("seed", [0, 1, 2**63 + 5])
def test_the_lane_stream_gives_numpys_raw_outputs(seed):
    """The 16 chains in 512-bit vectors (kernels.pcg64_lanes) against numpy's own outputs:
    refills of whole rounds at offsets that are not a multiple of 16, an empty one, and the
    chains' state carried from one refill to the next."""
    from activetrack.kernels import pcg64
    from activetrack.kernels.pcg64_lanes import LANES

    rng = np.random.default_rng(seed)
    words, _ = pcg64.stream_words(rng)
    want = np.random.default_rng(seed).bit_generator.random_raw(6000)
    chains, got = pcg64.new_stream(words), []
    for size, start in ((2048, 0), (2048, 5), (21, 7), (16, 16), (100, 3), (2048, 2000)):
        buf = np.zeros(size, dtype=np.uint64)
        end = pcg64.refill(chains, buf, start)
        assert end == start + (size - start) // LANES * LANES
        assert not buf[:start].any() and not buf[end:].any()  # nothing written outside
        got.append(buf[start:end])
    got = np.concatenate(got)
    assert got.size > 4000
    np.testing.assert_array_equal(got, want[: got.size])


def test_other_bit_generators_take_numbas_generator_route():
    """MT19937, Philox, ... are not PCG64: numba's generator support, the same bits."""
    from activetrack.kernels import particle, pcg64

    X = particles(300)
    F, L = np.eye(4), 0.5 * np.eye(4)
    for bits in (np.random.MT19937, np.random.Philox, np.random.PCG64DXSM):
        ours, ref = np.random.Generator(bits(7)), np.random.Generator(bits(7))
        assert not pcg64.pcg64_route(ours, "cv_rows", lambda: True)
        out, _ = particle.gaussian_sample(X, F, L, True, ours)
        np.testing.assert_array_equal(out, X + 0.5 * ref.standard_normal(X.shape))
        assert ours.random() == ref.random()


def test_a_failed_pcg64_check_warns_once_and_keeps_the_generic_route(monkeypatch):
    from activetrack.kernels import particle, pcg64

    monkeypatch.setattr(pcg64, "_checked", {})
    monkeypatch.setattr(particle, "_CHECKS", {True: lambda: False, False: lambda: False})
    X = particles(100)
    F, L = np.eye(4), np.eye(4)
    with pytest.warns(RuntimeWarning, match="does not reproduce this numpy's draws"):
        out, _ = particle.gaussian_sample(X, F, L, True, np.random.default_rng(3))
    np.testing.assert_array_equal(out, X + np.random.default_rng(3).standard_normal(X.shape))
    assert pcg64._checked == {"cv_rows": False}
    particle.gaussian_sample(X, F, L, True, np.random.default_rng(3))  # no second warning


def test_the_pcg64_check_passes_here():
    from activetrack.kernels import particle

    assert particle._pcg64_check(True)() and particle._pcg64_check(False)()


def test_the_models_pick_the_sampling_kernel_by_the_zeros_of_f_and_l():
    """NCV's F and L have the zeros of two constant-velocity axes (gaussian_sample's cv form,
    which the test above checks against the full sums); the discrete NCV's eigh factor and
    the turn model's F do not (its full sums)."""
    from activetrack.models._common import noise_factor
    from activetrack.models.ncv import has_cv_zeros

    def zeros(model):
        return has_cv_zeros(model.transition_matrix(5.0), noise_factor(model.process_noise(5.0)))

    assert zeros(NearlyConstantVelocity(0.01))
    assert not zeros(NearlyConstantVelocityDiscrete(0.3, 0.5))
    assert not zeros(ConstantTurn(0.05, 0.1))


def test_sampling_rejects_non_finite_particles_on_both_paths():
    for bad in (np.nan, np.inf, -np.inf):
        X = particles(10)
        X[4, 2] = bad
        for mode in ("numpy", "compiled"):
            kernels.set_kernels(mode)
            with pytest.raises(ValueError, match="x must be finite"):
                NearlyConstantVelocity(0.01).sample(X, 5.0, np.random.default_rng(0))


def test_sampling_takes_huge_finite_particles_on_both_paths():
    """Rows whose sum overflows are finite: the kernels' one-sum check calls it a false alarm
    (the caller checks X and goes on), with the numpy path's bits."""
    X = particles(10)
    X[3, [0, 2]] = 1.5e308
    (ref, out) = both(lambda: NearlyConstantVelocity(0.01).sample(X, 5.0, np.random.default_rng(0)))
    np.testing.assert_array_equal(out, ref)


@pytest.mark.parametrize("gate", [False, True])
@pytest.mark.parametrize(
    ("sensor", "z"),
    [
        (BearingSensor(0.01, r_min=1000.0, r_max=3500.0), [-2.4]),
        (BearingSensor(0.3), [3.1]),  # residuals across the +-pi seam, some behind
        (RangeBearingSensor(20.0, 0.02, r_min=1000.0, r_max=3500.0), [2500.0, -2.4]),
    ],
)
def test_likelihood_gives_the_same_bits(sensor, z, gate):
    X = particles()
    X[7, [0, 2]] = SENSOR_PV[[0, 2]]  # on the sensor: NaN on both paths (-inf if gated out)

    def ell():
        return sensor.log_likelihood(z, X, SENSOR_PV, gate=gate)

    (ref, c_ref), (out, c) = both(ell)
    np.testing.assert_array_equal(out, ref)
    assert c == c_ref
    assert np.isneginf(out[7]) if gate and sensor.r_min > 0 else np.isnan(out[7])
    if gate and sensor.r_min > 0:
        assert np.isneginf(out).sum() > 10  # particles inside r_min or beyond r_max


def test_likelihood_of_other_shapes_and_sensors_is_the_numpy_one():
    """Only (N, 4) particle arrays go through the kernel; another batch shape, or a sensor
    without a kernel (the ambiguous bearing, a custom sensor), runs its numpy maths."""
    x = particles(6).reshape(2, 3, 4)
    (ref, _), (out, _) = both(lambda: BearingSensor(0.01).log_likelihood([0.3], x, SENSOR_PV))
    assert out.shape == (2, 3)
    np.testing.assert_array_equal(out, ref)
    X = particles(50)
    strided = particles(100)[::2]  # the kernel reads rows flat: a strided view takes numpy's
    (ref, _), (out, _) = both(lambda: BearingSensor(0.01).log_likelihood([0.3], strided, SENSOR_PV))
    np.testing.assert_array_equal(out, ref)
    for sensor, z in ((AmbiguousBearingSensor(0.05), [0.4]), (LinearPositionSensor(20.0), [5, 3])):
        (ref, _), (out, _) = both(lambda s=sensor, z=z: s.log_likelihood(z, X, SENSOR_PV))
        np.testing.assert_array_equal(out, ref)


@pytest.mark.parametrize("spread", [0.5, 5.0, 50.0])
def test_systematic_resampling_picks_the_same_rows(spread):
    from activetrack.kernels import particle

    rng = np.random.default_rng(int(spread * 10))
    X = rng.standard_normal((4000, 4))
    ell = -0.5 * (spread * rng.standard_normal(4000)) ** 2
    w = np.exp(ell - ell.max())
    w /= w.sum()
    for u in (0.0, rng.random(), 1.0 - 2.0**-53):
        idx = systematic_indices(w, u)
        np.testing.assert_array_equal(particle.systematic_indices(w, u), idx)
        np.testing.assert_array_equal(particle.systematic_resample_rows(X, w, u), X[idx])
    one = np.ones(1)
    assert particle.systematic_indices(one, 0.5).tolist() == [0]


def bearing_run(pf_options, model=None, sensor=None, steps=8, n=3000):
    """Estimates, weights, ESS and log-likelihoods of a seeded PF run with two sensors."""
    model = model or NearlyConstantVelocity(0.01)
    sensor = sensor or BearingSensor(0.01, r_min=500.0)
    second = RangeBearingSensor(30.0, 0.02)
    f = ParticleFilter(
        model,
        x0=[0.0, 8.0, 0.0, 6.0],
        P0=np.diag([400.0, 1.0, 400.0, 1.0]),
        n_particles=n,
        rng=5,
        **pf_options,
    )
    out = []
    for k in range(1, steps + 1):
        t = 5.0 * k
        s1 = SENSOR_PV + np.array([-200.0 * k, 0.0, -150.0 * k, 0.0])
        s2 = np.array([-1500.0, 0.0, 1200.0, 0.0])
        z1 = None if k % 4 == 0 else [math.atan2(6.0 * t - s1[2], 8.0 * t - s1[0]) + 0.004]
        z2 = [
            math.hypot(8.0 * t - s2[0], 6.0 * t - s2[2]) - 10.0,
            math.atan2(6.0 * t - s2[2], 8.0 * t - s2[0]),
        ]
        info = f.step(t, [Measurement(sensor, s1, z1, t), Measurement(second, s2, z2, t)])
        exact = (f.particles.copy(), f.weights.copy(), info.ess, info.log_likelihood)
        out.append((exact, info.resampled, f.mean, f.cov))
    return out


@pytest.mark.parametrize(
    "options",
    [
        {},
        {"resample": "ess", "ess_threshold": 0.6},
        {"min_range": "negative", "roughening": 0.2},
    ],
)
def test_filter_runs_give_the_same_bits(options):
    """Particles, weights, ESS and log-likelihoods: the same bits. The mean and covariance
    come from the compiled moments in compiled mode (particle-order sums against numpy's
    BLAS): 1e-12."""
    ref, out = both(lambda: bearing_run(options))
    assert len(ref) == len(out)
    resampled = []
    for (exact_ref, res_ref, m_ref, P_ref), (exact, res, m, P) in zip(ref, out, strict=True):
        for x, y in zip(exact_ref, exact, strict=True):
            np.testing.assert_array_equal(y, x)
        assert res == res_ref
        resampled.append(res)
        np.testing.assert_allclose(m, m_ref, rtol=1e-12, atol=1e-12 * np.abs(m_ref).max())
        np.testing.assert_allclose(P, P_ref, rtol=0, atol=1e-12 * np.abs(P_ref).max())
    if options.get("resample") == "ess":
        assert any(resampled) and not all(resampled)  # both branches ran


def test_compiled_moments_agree_with_numpy():
    from activetrack.kernels import moments

    rng = np.random.default_rng(8)
    X = particles(3000)
    w = rng.random(3000)
    w /= w.sum()
    mean, cov = moments.weighted_moments4(X, w)
    ref_mean = w @ X
    D = X - ref_mean
    ref_cov = (D.T * w) @ D
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-12)
    np.testing.assert_allclose(cov, ref_cov, rtol=0, atol=1e-12 * np.abs(ref_cov).max())
    assert np.array_equal(cov, cov.T)
    w.flags.writeable = False  # the filter's uniform weights are read-only
    np.testing.assert_array_equal(moments.weighted_moments4(X, w)[0], mean)


def test_custom_sensor_and_nonlinear_model_fall_back_to_numpy():
    """A custom sensor (the test's linear one) and a model without a kernel (Valverde's
    circular motion, 5-D and not pv) run their own numpy maths on the compiled path too; the
    filter's resampling is still compiled, with the same bits."""
    model = CircularMotion(0.001, 0.05)
    x0 = [0.3, 0.0, 0.0, 0.01, 10.0]

    def run():
        f = ParticleFilter(model, x0=x0, P0=np.eye(5) * 0.1, n_particles=2000, rng=9)
        sensor = LinearPositionSensor(20.0)
        for k in range(1, 6):
            f.step(5.0 * k, [Measurement(sensor, np.zeros(4), [40.0 * k, 3.0], 5.0 * k)])
        return f.particles.copy(), f.mean

    (X_ref, m_ref), (X, m) = both(run)
    np.testing.assert_array_equal(X, X_ref)
    np.testing.assert_array_equal(m, m_ref)


def test_auto_mode_switches_after_enough_work(monkeypatch):
    """``auto`` starts on numpy and loads the kernels once the counted work passes
    AUTO_WORK (or numba is already imported); ``numpy`` never does."""
    from activetrack.kernels import particle  # loaded before numba leaves sys.modules below

    monkeypatch.setattr(kernels, "_particle", None)
    monkeypatch.setattr(kernels, "_work", 0)
    monkeypatch.setattr(kernels, "AUTO_WORK", 100)
    monkeypatch.delitem(__import__("sys").modules, "numba")
    kernels.set_kernels("auto")
    assert kernels.particle_kernels(work=60) is None
    assert kernels.particle_kernels(work=60) is particle  # 120 >= 100
    kernels.set_kernels("numpy")
    assert kernels.particle_kernels(work=10**9) is None


def test_announced_work_loads_the_kernels_before_any_update(monkeypatch):
    """``expect_particle_work`` (a Monte Carlo about to fork its workers) counts towards
    AUTO_WORK at once: the kernels load in the parent, before a single particle update."""
    from activetrack.kernels import particle

    monkeypatch.setattr(kernels, "_particle", None)
    monkeypatch.setattr(kernels, "_work", 0)
    monkeypatch.setattr(kernels, "AUTO_WORK", 100)
    monkeypatch.delitem(__import__("sys").modules, "numba")
    kernels.set_kernels("auto")
    kernels.expect_particle_work(99)
    assert kernels.particle_kernels() is None
    kernels.expect_particle_work(1)
    assert kernels._particle is particle
    assert kernels.particle_kernels() is particle


@pytest.mark.parametrize(("steps", "loads"), [(30, False), (600, True)])
def test_a_tracker_announces_its_runs_particle_work(monkeypatch, steps, loads):
    """A closed-loop tracker (a tracker node's core) with a particle filter announces its
    run's work (steps x particles) when it is built: a long run loads the kernels before its
    first update instead of pausing in mid-run; a short one (``make run``) never loads them."""
    from activetrack.closed_loop.components import build_tracker
    from activetrack.scenarios import load_scenario

    monkeypatch.setattr(kernels, "_particle", None)
    monkeypatch.setattr(kernels, "_work", 0)
    monkeypatch.delitem(__import__("sys").modules, "numba")
    kernels.set_kernels("auto")
    scenario = load_scenario("scenarios/default.yaml")
    assert scenario.tracker.particles * 30 < kernels.AUTO_WORK <= scenario.tracker.particles * 600
    scenario = scenario.model_copy(update={"steps": steps})
    build_tracker(scenario, np.random.default_rng(0))
    assert (kernels._particle is not None) == loads


def test_mode_names_are_checked(monkeypatch):
    with pytest.raises(ValueError, match="ACTIVETRACK_KERNELS"):
        kernels.set_kernels("fast")
    monkeypatch.setenv("ACTIVETRACK_KERNELS", "Numpy")
    kernels.set_kernels(None)
    assert not kernels.compiled_enabled()


# --- the EKF kernels (compiled mode only; round-off agreement) ---------------------------------


def ekf_run(model, x0, P0, steps=12):
    """Means, covariances, NIS and log-likelihoods of a seeded EKF run with a bearing and a
    range-bearing sensor (one update has both, one has a missed detection)."""
    f = ExtendedKalmanFilter(model, x0, P0)
    bearing, rb = BearingSensor(0.01), RangeBearingSensor(20.0, 0.02)
    rng = np.random.default_rng(4)
    out = []
    for k in range(1, steps + 1):
        t = 5.0 * k
        s1 = np.array([1800.0 - 150.0 * k, -30.0, 2000.0 - 100.0 * k, -20.0])
        s2 = np.array([-1500.0, 0.0, 1200.0, 0.0])
        truth = np.array([8.0 * t, 8.0, 6.0 * t, 6.0])
        z1 = None if k % 5 == 0 else bearing.sample(truth, s1, rng)
        z2 = rb.sample(truth, s2, rng)
        info = f.step(t, [Measurement(bearing, s1, z1, t), Measurement(rb, s2, z2, t)])
        out.append((f.mean, f.cov, info.nis, info.log_likelihood))
    return out


@pytest.mark.parametrize(
    ("model", "x0", "P0"),
    [
        (NearlyConstantVelocity(0.01), [0.0, 8.0, 0.0, 6.0], np.diag([400.0, 1.0, 400.0, 1.0])),
        (CircularMotion(0.001, 0.05), [0.64, 0.0, 0.0, 0.001, 10.0], np.eye(5) * 0.5),
    ],
)
def test_ekf_kernels_agree_with_the_numpy_ekf(model, x0, P0):
    """Compiled mode runs the EKF kernels (loop-order sums where numpy's matmul uses BLAS):
    the same estimates to round-off, checked to 1e-12 relative (the covariances to 1e-12 of
    their largest entry)."""
    kernels.set_kernels("auto")
    assert kernels.ekf_kernels() is None  # never in auto: not bit-identical
    ref, out = both(lambda: ekf_run(model, np.array(x0), P0))
    for (m_ref, P_ref, nis_ref, ll_ref), (m, P, nis, ll) in zip(ref, out, strict=True):
        np.testing.assert_allclose(m, m_ref, rtol=1e-12, atol=1e-12 * np.abs(m_ref).max())
        np.testing.assert_allclose(P, P_ref, rtol=0, atol=1e-12 * np.abs(P_ref).max())
        assert nis == pytest.approx(nis_ref, rel=1e-11)
        assert ll == pytest.approx(ll_ref, rel=1e-12)


def test_ekf_kernel_rejects_a_non_positive_innovation_covariance():
    from activetrack.kernels import ekf

    x, P = np.zeros(4), np.eye(4)
    for R in (np.array([[-5.0]]), np.diag([1.0, -5.0])):
        H = np.zeros((R.shape[0], 4))
        assert not ekf.update(x, P, H, np.zeros(R.shape[0]), R)[-1]
