"""The compiled PCRLB pieces equal the numpy reference: the sensors' Fisher-information kernels
(Hernandez eq. 8-9), the prediction step of eq. 3 and b_k of eq. 10 to 1e-12; and the planner
with its compiled search bookkeeping, candidate legs, kernels and per-platform J_Z cache takes the
decisions it took before them (paths recorded from the numpy planner on the Hernandez
scenarios, scenario seed)."""

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from linear_sensor import LinearPositionSensor

from activetrack.bounds import measurement_information, rmse_bound_of_information
from activetrack.bounds.pcrlb import (
    information_function,
    information_kernel,
    pcrlb_trajectory,
    predicted_information,
)
from activetrack.kernels import KERNEL_MODULES, kernels_enabled, prefer_kernels, warm_up
from activetrack.models.clutter import ClutteredSensor
from activetrack.models.sensors import (
    AmbiguousBearingSensor,
    BearingSensor,
    RangeBearingSensor,
    RangeRateBearingSensor,
)
from activetrack.planning.searches import quadrant_search
from activetrack.scenarios import load_scenario
from activetrack_experiments.hernandez import plan_case

SCENARIOS = Path(__file__).parents[2] / "scenarios"


@pytest.fixture(autouse=True)
def compiled(monkeypatch):
    """The compiled kernels on (activetrack.kernels: else only for heavy decisions)."""
    monkeypatch.setenv("ACTIVETRACK_KERNELS", "compiled")


def _samples(M: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal([0.0, 8.0, 0.0, 6.0], [300.0, 1.0, 300.0, 1.0], size=(M, 4))


def _states(shape: tuple[int, ...], seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal([100.0, -40.0, 200.0, -40.0], [300.0, 1.0, 300.0, 1.0], size=(*shape, 4))


def _close(a: np.ndarray, b: np.ndarray) -> None:
    """Equal to 1e-12 relative to the largest entry (only the summation order differs)."""
    scale = float(np.max(np.abs(b)))
    assert scale > 0.0
    np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-12 * scale)


def _kernel_and_numpy(sensor, S: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The sensor's J_Z through its compiled kernel (which it must have) and through its numpy
    form, checked equal to 1e-12 of the largest entry: ``(auto, ref)``."""
    assert information_kernel(sensor) is not None
    auto = measurement_information(sensor, S, X)
    ref = measurement_information(sensor, S, X, method="numpy")
    assert auto.shape == ref.shape == (*S.shape[:-1], 4, 4)
    _close(auto, ref)
    return auto, ref


@pytest.mark.parametrize(
    "sensor",
    [
        BearingSensor(sigma=0.01),
        BearingSensor(sigma=0.02, pd=0.7, r_min=150.0),
        BearingSensor(sigma=0.005, r_min=100.0, r_max=600.0),
        AmbiguousBearingSensor(sigma=0.03, pd=0.9, r_min=50.0, r_max=900.0),
    ],
)
@pytest.mark.parametrize("shape", [(1,), (9,), (5, 9), (3, 4, 5)])
def test_bearing_kernel_equals_the_numpy_closed_form(sensor, shape):
    X, S = _samples(1000), _states(shape)
    _, ref = _kernel_and_numpy(sensor, S, X)
    # The masks of eq. 8's I_r must bite in these cases: some samples in range, some not.
    if sensor.r_min > 0.0:
        flat = S.reshape(-1, 4)
        r = np.hypot(X[:, 0] - flat[:, None, 0], X[:, 2] - flat[:, None, 2])
        inside = (r >= sensor.r_min) & (r <= sensor.r_max)
        assert inside.any() and not inside.all()
    # And the Jacobian form of eq. 8 agrees with both (to its own round-off).
    np.testing.assert_allclose(
        measurement_information(sensor, S, X, method="jacobian"), ref, rtol=1e-9, atol=1e-15
    )


@pytest.mark.parametrize(
    "sensor",
    [
        RangeBearingSensor(sigma_r=5.0, sigma_b=0.02),
        RangeBearingSensor(sigma_r=8.0, sigma_b=0.02, pd=0.8, r_min=150.0, r_max=700.0),
        ClutteredSensor(RangeBearingSensor(sigma_r=10.0, sigma_b=0.01, pd=0.9), 5.0),
    ],
)
@pytest.mark.parametrize("shape", [(1,), (9,), (5, 9)])
def test_range_bearing_kernel_equals_the_generic_jacobian_form(sensor, shape):
    """The range-bearing sensor's compiled eq. 8 (its closed form for H = (range row, bearing
    row), R diagonal) against its generic numpy form, G^T G with G = R^(-1/2) H, to 1e-12 of
    the largest entry; both terms matter (neither noise dominates the other here)."""
    X, S = _samples(1000), _states(shape)
    _, ref = _kernel_and_numpy(sensor, S, X)
    base = getattr(sensor, "base", sensor)
    range_only = RangeBearingSensor(base.sigma_r, 1e9, base.pd, base.r_min, base.r_max)
    bearing_only = RangeBearingSensor(1e9, base.sigma_b, base.pd, base.r_min, base.r_max)
    parts = [measurement_information(s, S, X, method="numpy") for s in (range_only, bearing_only)]
    assert min(float(np.abs(p[..., 0, 0]).max()) for p in parts) > 0.05 * float(
        np.abs(ref[..., 0, 0]).max()
    )


@pytest.mark.parametrize(
    "sensor",
    [
        RangeRateBearingSensor(sigma_r=5.0, sigma_rr=0.5, sigma_b=0.02),
        RangeRateBearingSensor(sigma_r=8.0, sigma_rr=0.2, sigma_b=0.01, pd=0.7, r_min=150.0),
    ],
)
@pytest.mark.parametrize("shape", [(1,), (9,), (4, 6)])
def test_range_rate_bearing_kernel_equals_the_generic_jacobian_form(sensor, shape):
    """The Doppler sensor's range-rate row depends on the relative velocity and fills all of
    J_Z, velocity block included: the compiled closed form equals the generic numpy form to
    1e-12 of the largest entry, and the velocity entries are not zero."""
    X, S = _samples(1000), _states(shape)
    auto, ref = _kernel_and_numpy(sensor, S, X)
    assert float(np.abs(ref[..., 1, 1]).min()) > 0.0 and float(np.abs(ref[..., 0, 1]).max()) > 0.0
    np.testing.assert_array_equal(auto, np.swapaxes(auto, -1, -2))


def test_range_bearing_kernel_rejects_a_sample_on_a_sensor():
    sensor = RangeBearingSensor(sigma_r=5.0, sigma_b=0.02)
    X, S = _samples(20), _states((3,))
    S[2, [0, 2]] = X[4, [0, 2]]
    with pytest.raises(ValueError, match="coincides with a sensor"):
        measurement_information(sensor, S, X)


def test_several_sensors_mix_kernels_and_numpy_forms():
    sensors = (
        BearingSensor(sigma=0.01, r_min=100.0),
        ClutteredSensor(BearingSensor(sigma=0.01), 5.0, fov_width=1.0),  # no kernel: numpy
        AmbiguousBearingSensor(sigma=0.02),
        RangeBearingSensor(sigma_r=5.0, sigma_b=0.02, r_min=100.0),
    )
    assert information_kernel(sensors[1]) is None
    X, S = _samples(700, seed=3), _states((6, 4), seed=4)
    _close(
        measurement_information(sensors, S, X),
        measurement_information(sensors, S, X, method="numpy"),
    )


def test_a_sensor_without_the_member_uses_its_fisher_information():
    @dataclass(frozen=True)
    class Bare:  # only the contract's members a PCRLB needs, no information_kernel at all
        inner: LinearPositionSensor

        def fisher_information(self, X, s, K=None):
            return self.inner.fisher_information(X, s, K)

    sensor = Bare(LinearPositionSensor(sigma=3.0))
    assert information_kernel(sensor) is None  # type: ignore[arg-type]
    f = information_function(sensor)  # type: ignore[arg-type]
    X, S = _samples(50), _states((4,))
    np.testing.assert_array_equal(f(X, S), sensor.inner.fisher_information(X, S))


def test_the_environment_switch_selects_the_numpy_forms(monkeypatch):
    sensor = BearingSensor(sigma=0.01)
    monkeypatch.setenv("ACTIVETRACK_KERNELS", "numpy")
    assert information_kernel(sensor) is None
    X, S = _samples(200), _states((7,))
    np.testing.assert_array_equal(
        measurement_information(sensor, S, X),
        measurement_information(sensor, S, X, method="numpy"),
    )


def test_kernel_rejects_a_sample_on_a_sensor():
    sensor = BearingSensor(sigma=0.01)
    X = _samples(20)
    S = _states((3,))
    S[1, [0, 2]] = X[7, [0, 2]]
    for method in ("auto", "numpy"):
        with pytest.raises(ValueError, match="coincides with a sensor"):
            measurement_information(sensor, S, X, method=method)


def test_trajectory_with_kernels_equals_numpy():
    F = np.eye(4)
    F[0, 1] = F[2, 3] = 5.0
    Q = 1e-3 * np.eye(4)
    J0 = np.diag([1 / 400, 1.0, 1 / 400, 1.0])
    sensors = (BearingSensor(sigma=0.01, r_min=50.0), BearingSensor(sigma=0.02))
    paths = _states((6, 8, 2), seed=9)
    X = _samples(400, seed=5)
    auto = pcrlb_trajectory(J0, F, Q, X, sensors, paths, np.random.default_rng(2))
    ref = pcrlb_trajectory(J0, F, Q, X, sensors, paths, np.random.default_rng(2), method="numpy")
    for J, J_ref in zip(auto.reshape(-1, 4, 4), ref.reshape(-1, 4, 4), strict=True):
        _close(J, J_ref)


# Sensor (x, y) positions after decisions 1-4, recorded from the numpy planner (quadrant search,
# 1,000 samples, scenario seed) before the compiled pieces; metres, 6 decimals.
RECORDED_PATHS = {
    "hernandez_1sensor_single": [
        [[1648.892571, 1703.434972]],
        [[1414.839991, 1400.469739]],
        [[1136.274783, 1137.8484]],
        [[903.241344, 900.193845]],
    ],
    "hernandez_1sensor_two": [
        [[1648.892571, 1703.434972]],
        [[1414.839991, 1400.469739]],
        [[1154.465361, 1154.997828]],
        [[930.471887, 943.824773]],
    ],
    "hernandez_2sensor_single": [
        [[1648.892571, 1703.434972], [1804.359962, 1730.724589]],
        [[1378.181893, 1432.724294], [1536.319983, 1457.369304]],
        [[1068.455632, 1207.694993], [1288.975322, 1109.803539]],
        [[728.126988, 1097.115514], [1146.157035, 655.112929]],
    ],
    "hernandez_2sensor_two": [
        [[1648.892571, 1703.434972], [1793.939091, 1738.612983]],
        [[1383.549125, 1427.461425], [1558.858152, 1440.414234]],
        [[1001.815933, 1223.420783], [1410.125522, 1037.256799]],
        [[575.714067, 1147.328645], [1311.9227, 567.698188]],
    ],
    "hernandez_3sensor_single": [
        [[1648.892571, 1703.434972], [1848.892571, 1703.434972], [1448.892571, 1703.434972]],
        [[1429.987717, 1389.350258], [1686.435379, 1384.59478], [1286.258551, 1413.031034]],
        [[1124.739315, 1158.283264], [1622.634722, 981.773288], [1060.202718, 1204.067171]],
        [[786.647357, 1041.043192], [1481.153543, 546.338993], [735.230301, 1054.252835]],
    ],
    "hernandez_3sensor_two": [
        [[1648.892571, 1703.434972], [1848.892571, 1703.434972], [1303.434972, 1848.892571]],
        [[1589.002776, 1325.305688], [1785.293446, 1325.911868], [944.255256, 1716.384178]],
        [[1483.830576, 905.434729], [1651.537692, 914.253986], [575.196174, 1490.224482]],
        [[1280.600809, 580.987192], [1580.689952, 436.637317], [159.979186, 1246.861594]],
    ],
}


@pytest.mark.parametrize("mode", ["compiled", "numpy"])
@pytest.mark.parametrize("name", sorted(RECORDED_PATHS))
def test_planner_takes_the_recorded_decisions(name, mode, monkeypatch):
    monkeypatch.setenv("ACTIVETRACK_KERNELS", mode)
    expected = np.array(RECORDED_PATHS[name])
    scenario = load_scenario(SCENARIOS / f"{name}.yaml")
    case = plan_case(scenario.model_copy(update={"steps": len(expected)}))
    # Same manoeuvres: positions equal to the recorded micrometre (a different choice of the
    # search moves a sensor by metres).
    np.testing.assert_allclose(case.paths[1:][..., [0, 2]], expected, rtol=0.0, atol=2e-6)
    assert math.isfinite(float(case.bounds.sum()))


def _spd_stack(N: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(N, 4, 4))
    scale = np.array([1e-3, 1.0, 1e-3, 1.0])  # pv information: position and velocity units
    J = A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(4)
    return 0.5 * (J + np.swapaxes(J, -1, -2)) * np.sqrt(np.outer(scale, scale))


def test_compiled_prediction_step_equals_numpy(monkeypatch):
    F = np.eye(4)
    F[0, 1] = F[2, 3] = 5.0
    block = np.array([[125 / 3, 12.5], [12.5, 5.0]])
    Q = 0.01 * np.kron(np.eye(2), block)  # NCV noise in (x, xdot, y, ydot) order
    J = _spd_stack(50, seed=7)
    auto = predicted_information(J, F, Q)
    monkeypatch.setenv("ACTIVETRACK_KERNELS", "numpy")
    ref = predicted_information(J, F, Q)
    for a, b in zip(auto, ref, strict=True):
        _close(a, b)
    monkeypatch.delenv("ACTIVETRACK_KERNELS")
    bad = J.copy()
    bad[3] = -bad[3]
    with pytest.raises(ValueError, match="J_prev must be symmetric positive definite"):
        predicted_information(bad, F, Q)
    bad = J.copy()
    bad[2, 0, 1] += 1.0
    with pytest.raises(ValueError, match="not symmetric"):
        predicted_information(bad, F, Q)


def test_compiled_rmse_bound_equals_numpy(monkeypatch):
    J = _spd_stack(60, seed=8).reshape(5, 12, 4, 4)
    auto = rmse_bound_of_information(J)
    monkeypatch.setenv("ACTIVETRACK_KERNELS", "numpy")
    ref = rmse_bound_of_information(J)
    assert auto.shape == ref.shape == (5, 12)
    np.testing.assert_allclose(auto, ref, rtol=1e-12, atol=0.0)
    assert rmse_bound_of_information(J[0, 0]).shape == ()
    monkeypatch.delenv("ACTIVETRACK_KERNELS")
    with pytest.raises(ValueError, match="singular"):
        rmse_bound_of_information(np.zeros((3, 4, 4)))
    with pytest.raises(ValueError, match="non-positive variance"):
        rmse_bound_of_information(-np.eye(4)[None])


@pytest.mark.parametrize("with_aux", [True, False])
@pytest.mark.parametrize("patience", [None, 2])
def test_compiled_quadrant_search_equals_numpy(monkeypatch, patience, with_aux):
    """Same points, costs, payloads and evaluations, ties and plateaus included (rounded costs
    make many exact ties, where the first index must win in both)."""
    centres = np.random.default_rng(4).uniform(0.0, 1.0, size=(7, 2))

    def cost_fn(rows, u):
        d = u - centres[rows, None, :]
        costs = np.round(4.0 * np.hypot(d[..., 0], d[..., 1]), 1)  # plateaus: exact ties
        if not with_aux:
            return costs
        return costs, np.stack([u[..., 0] * 2.0, u[..., 1] + rows[:, None]], axis=-1)

    results = {}
    for mode in ("compiled", "numpy"):
        monkeypatch.setenv("ACTIVETRACK_KERNELS", mode)
        results[mode] = quadrant_search(cost_fn, 7, divisions=6, patience=patience)
    a, b = results["compiled"], results["numpy"]
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.cost, b.cost)
    if with_aux:
        np.testing.assert_array_equal(a.payload(), b.payload())
    else:
        assert a.aux is None and b.aux is None
    assert a.evaluations == b.evaluations


def test_light_work_stays_on_numpy_whatever_the_process_ran_before(monkeypatch):
    """Without the environment variable: the kernels where a caller prefers them, not because
    numba is loaded (round-off kernels must not depend on a process's history); never with
    ACTIVETRACK_KERNELS=numpy."""
    monkeypatch.delenv("ACTIVETRACK_KERNELS", raising=False)
    monkeypatch.setitem(sys.modules, "numba", sys.modules.get("numba"))  # loaded
    assert not kernels_enabled()
    with prefer_kernels():
        assert kernels_enabled()
        with prefer_kernels(False):
            assert not kernels_enabled()
    assert not kernels_enabled()
    monkeypatch.setenv("ACTIVETRACK_KERNELS", "numpy")
    with prefer_kernels():
        assert not kernels_enabled()


def test_warm_up_readies_every_kernel_module():
    """``python -m activetrack.kernels`` (e.g. at setup) compiles or loads every kernel."""
    seconds = warm_up()
    assert tuple(seconds) == KERNEL_MODULES
    assert all(s >= 0.0 for s in seconds.values())


def test_a_sensor_in_clutter_scales_its_base_kernel_by_the_irf():
    """A wrapper that forwards unknown members to its base must not hand out the base's kernel
    unscaled: ClutteredSensor's own kernel is q / pd times the base's (its numpy form's maths)."""
    base = BearingSensor(sigma=0.01, pd=0.9, r_min=50.0)
    X, S = _samples(500), _states((3, 5))
    for sensor in (ClutteredSensor(base, clutter_density=10.0), ClutteredSensor(base)):
        assert information_kernel(sensor) is not None
        _close(
            measurement_information(sensor, S, X),
            measurement_information(sensor, S, X, method="numpy"),
        )
    ratio = ClutteredSensor(base, clutter_density=10.0).information_factor / 0.9
    assert ratio < 0.8  # the clutter does reduce the information
    sector = ClutteredSensor(base, clutter_density=10.0, fov_width=1.0)
    assert information_kernel(sector) is None  # the field of view's mask: the numpy form


def test_a_subclass_overriding_the_numpy_form_is_scored_by_its_override():
    @dataclass(frozen=True)
    class Halved(BearingSensor):
        def fisher_information(self, target_samples, sensor_pv, kinematics_jacobian=None):
            return 0.5 * super().fisher_information(target_samples, sensor_pv, kinematics_jacobian)

    sensor = Halved(sigma=0.01)
    assert information_kernel(sensor) is None

    @dataclass(frozen=True)
    class Doubled(RangeBearingSensor):  # another R: the generic form follows it, so no kernel
        @property
        def R(self):
            return 2.0 * super().R

    assert information_kernel(Doubled(sigma_r=5.0, sigma_b=0.02)) is None
    X, S = _samples(100), _states((4,))
    np.testing.assert_array_equal(
        measurement_information(sensor, S, X),
        0.5 * measurement_information(BearingSensor(sigma=0.01), S, X, method="numpy"),
    )


@pytest.mark.parametrize(
    ("batch", "M", "A"), [((), 50, 2), ((7,), 300, 2), ((3, 4), 40, 1), ((2,), 1, 3), ((5,), 80, 3)]
)
def test_jacobian_information_sums_are_the_einsum_bit_for_bit(batch, M, A):
    """The compiled sums of models.base.jacobian_information give the einsum's bits (they run
    whenever the particle kernels do, so a result must not depend on which one ran), zero
    weights (samples out of range) and weights broadcast over the batch included."""
    from activetrack.models._fisher_kernels import jacobian_information_sums

    rng = np.random.default_rng(3)
    G = rng.normal(scale=1e-2, size=(*batch, M, A, 4))
    for w in (rng.random((*batch, M)) * (rng.random((*batch, M)) < 0.8), rng.random(M)):
        got = jacobian_information_sums(G, w)
        np.testing.assert_array_equal(got, np.einsum("...mai,...maj,...m->...ij", G, G, w))
        assert got.shape == (*batch, 4, 4)


def test_jacobian_information_is_the_same_on_numpy_and_compiled(monkeypatch):
    """A radar's J_Z (the generic Jacobian form) over 200 samples at 6 sensor states, numpy
    mode against compiled mode: equal bits."""
    from activetrack import kernels

    sensor = RangeBearingSensor(sigma_r=30.0, sigma_b=0.01, pd=0.85, r_min=100.0, r_max=600.0)
    X, S = _samples(200), _states((6,))
    out = {}
    for mode in ("numpy", "compiled"):
        kernels.set_kernels(mode)
        out[mode] = sensor.fisher_information(X, S)
    kernels.set_kernels(None)
    assert np.count_nonzero(out["numpy"]) > 0
    np.testing.assert_array_equal(out["compiled"], out["numpy"])
