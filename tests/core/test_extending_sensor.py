"""A new sensor kind, defined in this file only and registered once, works everywhere.

The range-only sensor z = r + v, v ~ N(0, sigma_r^2) (the range row of Valverde eq. 10-13)
derives from ``GaussianSensor`` and defines only h, its Jacobian and R; its scenario config adds
``sigma_r``. Registered once, it runs through the EKF and the PF, the PCRLB (with the generic
Jacobian form of Hernandez eq. 8), PCRLB planning and a closed-loop batch run of a scenario
file, with nothing in the library special-casing it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, ClassVar, Literal

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter as FilterpyEKF
from pydantic import Field

from activetrack.bounds import covariance_bound, measurement_information, pcrlb_step, rmse_bound
from activetrack.closed_loop.batch import run_batch
from activetrack.filters import ExtendedKalmanFilter, Measurement, ParticleFilter
from activetrack.models import GaussianSensor, NearlyConstantVelocity
from activetrack.planning import (
    PlannerPlatform,
    PlanSettings,
    PlatformLimits,
    SearchSettings,
    TargetBelief,
    plan,
)
from activetrack.scenarios import (
    ScenarioError,
    SensorConfigBase,
    build_sensor,
    load_scenario,
    register_sensor,
    registered_kinds,
    sensor_kind,
    unregister_sensor,
)


@dataclass(frozen=True)
class RangeSensor(GaussianSensor):
    """Range only: z = sqrt(dx^2 + dy^2) + v, v ~ N(0, sigma_r^2) (Valverde eq. 10)."""

    sigma_r: float
    pd: float = 1.0
    r_min: float = 0.0
    r_max: float = math.inf

    kind: ClassVar[str] = "range"
    components: ClassVar[tuple[str, ...]] = ("range",)

    def __post_init__(self):
        if not (math.isfinite(self.sigma_r) and self.sigma_r > 0):
            raise ValueError(f"sigma_r must be finite and > 0, got {self.sigma_r!r}")
        self.validate_detection()

    @property
    def R(self):
        return np.array([[self.sigma_r**2]])

    def measure(self, target_pv, sensor_pv):
        d = np.asarray(target_pv, dtype=float) - np.asarray(sensor_pv, dtype=float)
        return np.hypot(d[..., 0], d[..., 2])[..., None]

    def jacobian(self, target_pv, sensor_pv):
        """d r / d (x, xdot, y, ydot) = (dx, 0, dy, 0) / r (Valverde eq. 13, first row)."""
        d = np.asarray(target_pv, dtype=float) - np.asarray(sensor_pv, dtype=float)
        dx, dy = d[..., 0], d[..., 2]
        r = np.hypot(dx, dy)
        zero = np.zeros_like(r)
        return np.stack([dx / r, zero, dy / r, zero], axis=-1)[..., None, :]


class RangeSensorConfig(SensorConfigBase):
    kind: Literal["range"]
    sigma_r: Annotated[float, Field(gt=0, le=1e4, allow_inf_nan=False)]  # m


@pytest.fixture(scope="module", autouse=True)
def range_kind():
    """Register the kind once for this module (and take it away afterwards): what the plugin
    module of docs/extending.md ("A sensor") does when a scenario names it."""
    register_sensor(RangeSensor, RangeSensorConfig)
    yield sensor_kind("range")
    unregister_sensor("range")


MODEL = NearlyConstantVelocity(q=0.05)
T = 2.0
X0 = np.array([300.0, 3.0, 400.0, -2.0])
P0 = np.diag([30.0**2, 1.0, 30.0**2, 1.0])
# Two still range sensors: together they fix the position (up to the mirror image).
STATIONS = [(RangeSensor(2.0), np.zeros(4)), (RangeSensor(2.0), np.array([600.0, 0, 0, 0]))]


def _truth_and_measurements(n_steps, seed):
    rng = np.random.default_rng(seed)
    x = X0 + np.linalg.cholesky(P0) @ rng.standard_normal(4)
    out = []
    for k in range(1, n_steps + 1):
        x = MODEL.sample(x, T, rng)
        ms = [
            Measurement(s, pv, s.sample(x, pv, rng), k * T, f"r{j}")
            for j, (s, pv) in enumerate(STATIONS)
        ]
        out.append((k * T, x.copy(), ms))
    return out


def test_registered_like_a_built_in(range_kind):
    assert registered_kinds()[:4] == (
        "bearing",
        "ambiguous_bearing",
        "range_bearing",
        "range_rate_bearing",
    )
    assert "range" in registered_kinds() and range_kind.sensor_class is RangeSensor
    # Registering the same classes again changes nothing; other classes under its name fail.
    assert register_sensor(RangeSensor, RangeSensorConfig) is range_kind
    with pytest.raises(ValueError, match="registered already"):
        register_sensor(type("Other", (RangeSensor,), {}), RangeSensorConfig)


def test_linearization_matches_finite_differences():
    sensor, s = RangeSensor(2.0), np.array([50.0, 1.0, -20.0, 0.5])
    x, z = np.array([310.0, 2.0, 380.0, -1.0]), np.array([460.0])
    lin = sensor.linearize(x, s, z)
    eps = 1e-4
    fd = np.stack(
        [
            (sensor.measure(x + eps * e, s) - sensor.measure(x - eps * e, s))[0] / (2 * eps)
            for e in np.eye(4)
        ]
    )
    np.testing.assert_allclose(lin.H, fd[None, :], rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(lin.nu, z - sensor.measure(x, s), rtol=0, atol=1e-12)


def test_ekf_update_equals_filterpy_and_tracks():
    steps = _truth_and_measurements(12, seed=3)
    ekf = ExtendedKalmanFilter(MODEL, X0, P0)
    fp = FilterpyEKF(dim_x=4, dim_z=1)
    fp.x, fp.P = X0.copy(), P0.copy()
    fp.F, fp.Q = MODEL.transition_matrix(T), MODEL.process_noise(T)
    for t, _, ms in steps:
        info = ekf.step(t, ms)
        fp.predict()
        for m in ms:
            s = m.sensor_state
            fp.update(
                m.z,
                HJacobian=lambda x, s=s: RangeSensor(2.0).jacobian(x, s),
                Hx=lambda x, s=s: RangeSensor(2.0).measure(x, s),
                R=m.sensor.R,
            )
        assert info.n_detections == 2 and math.isfinite(info.nis)
    np.testing.assert_allclose(ekf.mean, fp.x, rtol=0, atol=1e-8)
    np.testing.assert_allclose(ekf.cov, fp.P, rtol=1e-9, atol=1e-9)
    truth = steps[-1][1]
    assert np.hypot(*(ekf.mean - truth)[[0, 2]]) < 15.0


def test_pf_weights_are_the_range_likelihood_and_track():
    pf = ParticleFilter(MODEL, X0, P0, n_particles=4000, rng=7, resample="ess", ess_threshold=0)
    sensor, s, z = STATIONS[0][0], STATIONS[0][1], np.array([505.0])
    X = pf.particles.copy()
    info = pf.update([Measurement(sensor, s, z, 0.0)])
    logw = -0.5 * ((z[0] - np.hypot(X[:, 0], X[:, 2])) / 2.0) ** 2
    w = np.exp(logw - logw.max())
    np.testing.assert_allclose(pf.weights, w / w.sum(), rtol=1e-9, atol=1e-300)
    assert math.isfinite(info.log_likelihood) and not info.resampled

    steps = _truth_and_measurements(12, seed=4)
    pf = ParticleFilter(MODEL, X0, P0, n_particles=4000, rng=8)
    for t, _, ms in steps:
        pf.step(t, ms)
    assert np.hypot(*(pf.mean - steps[-1][1])[[0, 2]]) < 15.0


def test_default_fisher_information_is_the_range_closed_form():
    """The generic Jacobian form equals H^T R^-1 H with H = (dx, 0, dy, 0) / r, with pd and
    the detection ranges (Hernandez eq. 8), for candidates batched over leading axes."""
    rng = np.random.default_rng(5)
    X = rng.normal([300.0, 3.0, 400.0, -2.0], [60.0, 1.0, 60.0, 1.0], size=(500, 4))
    sensor = RangeSensor(2.0, pd=0.8, r_min=420.0, r_max=560.0)
    states = np.zeros((3, 2, 4))
    states[..., 0] = rng.uniform(-50.0, 50.0, (3, 2))
    states[..., 2] = rng.uniform(-50.0, 50.0, (3, 2))
    J = measurement_information(sensor, states, X)

    dx = X[:, 0] - states[..., 0, None]  # (3, 2, M)
    dy = X[:, 2] - states[..., 2, None]
    r = np.hypot(dx, dy)
    w = sensor.pd * ((r >= sensor.r_min) & (r <= sensor.r_max)) / X.shape[0]
    assert 0.1 < np.mean(w > 0) < 0.9  # the ranges really cut samples
    H = np.stack([dx / r, 0 * r, dy / r, 0 * r], axis=-1)  # (3, 2, M, 4)
    closed = np.einsum("...mi,...mj,...m->...ij", H, H, w) / sensor.sigma_r**2
    assert J.shape == (3, 2, 4, 4)
    assert np.max(np.abs(J - closed)) <= 1e-9 * np.max(np.abs(closed))
    np.testing.assert_array_equal(J, measurement_information(sensor, states, X, method="jacobian"))


def test_pcrlb_planning_with_the_range_sensor():
    """Single-step planning (Hernandez eq. 11) of a platform carrying the range sensor."""
    rng = np.random.default_rng(6)
    F, Q = MODEL.transition_matrix(T), MODEL.process_noise(T)
    belief = TargetBelief.from_gaussian(X0, P0, 400, rng)
    limits = PlatformLimits(dpsi_max=math.pi / 4, dv_max=5.0, v_min=10.0, v_max=40.0)
    robot = PlannerPlatform("robot", np.array([0.0, 20.0, 0.0, 0.0]), (RangeSensor(2.0),), limits)
    still = PlannerPlatform("still", np.array([600.0, 0.0, 0.0, 0.0]), (RangeSensor(2.0),))
    settings = PlanSettings(criterion="b_k", horizon=1, search=SearchSettings(search="grid"))
    result = plan([robot, still], belief, settings, F=F, Q=Q, dt=T)
    assert result.report.evaluations > 100

    def bound_after(robot_next_pv):
        """b_k (eq. 10) of eq. 3 with both sensors' J_Z at their positions at k+1."""
        X1 = belief.samples @ F.T  # noise-free propagation (rng=None)
        states = np.stack([robot_next_pv, still.pv])  # the buoy is still
        J_Z = measurement_information([RangeSensor(2.0)] * 2, states, X1)
        J = pcrlb_step(belief.J, F, Q, J_Z)
        return J, float(rmse_bound(covariance_bound(J)))

    J_next, b_k = bound_after(result.manoeuvre("robot").next_pv)
    np.testing.assert_allclose(result.J_next, J_next, rtol=1e-9)
    assert result.report.objective == pytest.approx(b_k, rel=1e-9)
    # Better than holding course (the robot heads east, along the buoy's baseline).
    _, b_hold = bound_after(robot.pv + T * np.array([robot.pv[1], 0.0, robot.pv[3], 0.0]))
    assert b_k < b_hold


SCENARIO = """\
name: range_only
seed: 3
dt: 2.0
steps: 15
target:
  motion: {model: ncv, q: 0.05}
  prior: {mean: [300.0, 3.0, 400.0, -2.0], var: [900.0, 1.0, 900.0, 1.0]}
platforms:
  - id: robot
    initial_state: [0.0, 20.0, 0.0, 0.0]
    controllable: true
    limits: {dpsi_max: 0.7853981633974483, dv_max: 5.0, v_min: 10.0, v_max: 40.0}
    sensors:
      - {id: r1, kind: range, sigma_r: 2.0}
  - id: buoy
    initial_state: [600.0, 0.0, 0.0, 0.0]
    sensors:
      - {id: r2, kind: range, sigma_r: 2.0, pd: 0.9}
tracker: {filter: ekf}
planner: {cost: pcrlb, criterion: b_k, horizon: 1, search: quadrant, mode: renewal, mc_samples: 200}
"""


def test_closed_loop_batch_run_of_a_scenario_file(tmp_path):
    path = tmp_path / "range_only.yaml"
    path.write_text(SCENARIO)
    scenario = load_scenario(path)
    assert build_sensor(scenario.platforms[1].sensors[0]) == RangeSensor(2.0, pd=0.9)
    summary = run_batch(scenario)
    assert summary.steps == 15 and summary.evaluations_per_decision > 0
    for value in (
        summary.time_avg_rmse_x[0],
        summary.time_avg_rmse_y[0],
        summary.time_avg_bound_x[0],
        summary.time_avg_bound_y[0],
    ):
        assert math.isfinite(value) and 0.0 < value < 10.0  # prior std 30 m


def test_scenario_errors_name_the_new_kind_and_its_fields(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(SCENARIO.replace("sigma_r: 2.0, pd", "sigma_r: -1.0, pd"))
    with pytest.raises(ScenarioError, match=r"platforms\.1\.sensors\.0\.range\.sigma_r"):
        load_scenario(path)
    path.write_text(SCENARIO.replace("kind: range, sigma_r: 2.0}", "kind: sonar, sigma_r: 2.0}"))
    with pytest.raises(ScenarioError, match="must be one of .*'range_rate_bearing', 'range'"):
        load_scenario(path)
    with pytest.raises(ValueError, match=r"sensors\.kind: must be one of .*'range'"):
        build_sensor(RangeSensorConfig.model_construct(id="x", kind="sonar", sigma_r=1.0))
