"""A new filter, defined in this file only and registered once, runs closed loop from a scenario.

The filter is filterpy's UnscentedKalmanFilter wrapped to the TrackingFilter protocol
(activetrack.filters.measurement): any motion model, any sensor (h through the sensor
contract). Registered under ``ukf`` (activetrack.filters.registry), ``tracker: {filter: ukf}``
loads and the tracker (``closed_loop.components.build_tracker``) builds it; the plugin module
of docs/extending.md ("A filter", the same code as here, checked by test_extending_docs.py)
makes a scenario file name it itself. A filter in a scene of several targets or clutter also
needs ``update_pda``: tests/plugins_for_tests.py and test_plugins.py.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest
import yaml
from doc_blocks import file_block
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

from activetrack.closed_loop.batch import run_batch
from activetrack.closed_loop.components import build_tracker
from activetrack.filters import (
    ExtendedKalmanFilter,
    Measurement,
    UpdateInfo,
    filter_kind,
    filter_names,
    make_filter,
    register_filter,
    unregister_filter,
)
from activetrack.filters.measurement import check_measurement_times, check_predict_time
from activetrack.models import GaussianSensor, NearlyConstantVelocity
from activetrack.scenarios import ScenarioError, load_scenario, parse_scenario
from activetrack.scenarios.load import with_tracker_overrides
from activetrack_bringup.cli import main as cli_main

_LOG_2PI = math.log(2.0 * math.pi)


class UnscentedFilter:
    """filterpy's UnscentedKalmanFilter behind the TrackingFilter protocol.

    Any motion model (f = model.propagate, Q = model.process_noise) and any sensor: h is
    sensor.measure of the state's kinematics, residuals are sensor.residual (angles wrapped).
    Measurements of one time are fused one after another, each with sigma points of the
    current (x, P). Merwe's scaled sigma points with alpha = 1, beta = 2, kappa = 0.
    """

    def __init__(self, model, x0, P0, t0=0.0):
        n = model.dim
        points = MerweScaledSigmaPoints(n, alpha=1.0, beta=2.0, kappa=0.0)
        self.model = model
        self.ukf = UnscentedKalmanFilter(
            dim_x=n, dim_z=1, dt=1.0, hx=None, fx=model.propagate, points=points
        )
        self.ukf.x = np.array(x0, dtype=float)
        self.ukf.P = np.array(P0, dtype=float)
        self._t = float(t0)

    @property
    def time(self):
        return self._t

    @property
    def mean(self):
        return self.ukf.x.copy()

    @property
    def cov(self):
        return 0.5 * (self.ukf.P + self.ukf.P.T)

    def predict(self, t):
        t = check_predict_time(t, self._t)
        if t > self._t:
            dt = t - self._t
            self.ukf.Q = self.model.process_noise(dt, self.ukf.x)
            self.ukf.predict(dt=dt)
        self._t = t

    def update(self, measurements):
        check_measurement_times(measurements, self._t)
        nis_each, log_lik, dof = [], 0.0, 0
        for m in measurements:
            if m.z is None:  # looked and saw nothing: no update
                nis_each.append(math.nan)
                continue
            nis, log_lik_m = self._fuse(m)
            nis_each.append(nis)
            log_lik += log_lik_m
            dof += len(m.z)
        detected = [v for v in nis_each if not math.isnan(v)]
        return UpdateInfo(
            time=self._t,
            n_detections=len(detected),
            n_missed=len(nis_each) - len(detected),
            nis=sum(detected) if detected else math.nan,
            dof=dof,
            nis_per_measurement=tuple(nis_each),
            log_likelihood=log_lik,
            sensor_ids=tuple(m.sensor_id for m in measurements),
        )

    def _fuse(self, m):
        """One detection, from sigma points of the current (x, P): (NIS, log-likelihood)."""
        ukf, sensor, s = self.ukf, m.sensor, m.sensor_state
        ukf.sigmas_f = ukf.points_fn.sigma_points(ukf.x, ukf.P)
        ukf.residual_z = sensor.residual
        ukf.z_mean = lambda Z, Wm: Z[0] + Wm @ sensor.residual(Z, Z[0])
        ukf.update(m.z, R=sensor.R, hx=lambda x: sensor.measure(self.model.kinematics(x), s))
        ukf.P = 0.5 * (ukf.P + ukf.P.T)
        nis = float(ukf.y @ ukf.SI @ ukf.y)
        return nis, -0.5 * (nis + np.linalg.slogdet(ukf.S)[1] + len(m.z) * _LOG_2PI)

    def step(self, t, measurements):
        self.predict(t)
        return self.update(measurements)


def make_ukf(model, x0, P0, config, rng):
    """The registry's factory: the UKF takes no option of the tracker block, no random draws."""
    return UnscentedFilter(model, x0, P0)


@pytest.fixture
def ukf():
    """``ukf`` registered for one test (and taken away afterwards): what the plugin module of
    docs/extending.md does when a scenario names it."""
    register_filter("ukf", make_ukf, description="unscented Kalman filter (filterpy)")
    yield filter_kind("ukf")
    unregister_filter("ukf")


@pytest.fixture
def plugin_folder(tmp_path, monkeypatch):
    """tmp_path on the import path, holding docs/extending.md's plugin module ``my_filters``;
    the registration and the imported module are undone afterwards."""
    (tmp_path / "my_filters.py").write_text(file_block("my_filters.py"))
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    for name in ("my_filters", "bad_filters"):
        sys.modules.pop(name, None)
    if "ukf" in filter_names():
        unregister_filter("ukf")


# Two bearings-only sensors, one steered by PCRLB planning (docs/extending.md, "A filter").
SCENARIO = """\
name: ukf_bearings
seed: 11
plugins: [my_filters]
dt: 2.0
steps: 20
target:
  motion: {model: ncv, q: 0.05}
  prior: {mean: [1000.0, 3.0, 1200.0, -2.0], var: [2500.0, 1.0, 2500.0, 1.0]}
platforms:
  - id: robot
    initial_state: [0.0, 15.0, 0.0, 0.0]
    controllable: true
    limits: {dpsi_max: 0.5, dv_max: 5.0, v_min: 10.0, v_max: 30.0}
    sensors:
      - {id: b1, kind: bearing, sigma: 0.01}
  - id: buoy
    initial_state: [2000.0, 0.0, 0.0, 0.0]
    sensors:
      - {id: b2, kind: bearing, sigma: 0.01}
tracker: {filter: ukf}
planner: {cost: pcrlb, criterion: b_k, search: quadrant, mc_samples: 200}
"""


def without_plugins(text: str) -> str:
    """The scenario for a process that registered ``ukf`` itself (the ``ukf`` fixture)."""
    data = yaml.safe_load(text)
    del data["plugins"]
    return yaml.safe_dump(data, sort_keys=False)


@dataclass(frozen=True)
class PositionSensor(GaussianSensor):
    """z = (x, y) - (x_s, y_s) + v: linear, so the UKF must equal the Kalman filter."""

    sigma: float
    pd: float = 1.0
    r_min: float = 0.0
    r_max: float = math.inf

    kind: ClassVar[str] = "position"
    components: ClassVar[tuple[str, ...]] = ("dx", "dy")

    @property
    def R(self):
        return self.sigma**2 * np.eye(2)

    def measure(self, target_pv, sensor_pv):
        d = np.asarray(target_pv, dtype=float) - np.asarray(sensor_pv, dtype=float)
        return d[..., [0, 2]]

    def jacobian(self, target_pv, sensor_pv):
        shape = np.broadcast_shapes(np.shape(target_pv), np.shape(sensor_pv))[:-1]
        return np.broadcast_to(np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]]), (*shape, 2, 4))


def test_the_ukf_is_the_kalman_filter_on_a_linear_problem():
    """Linear dynamics (NCV) and a linear sensor: the unscented transform is exact, so the UKF
    equals the EKF (which is the Kalman filter there) in mean, covariance, NIS and likelihood,
    over several epochs with two sensors fused per epoch and a missed look."""
    model = NearlyConstantVelocity(q=0.05)
    x0, P0 = np.array([300.0, 3.0, 400.0, -2.0]), np.diag([900.0, 1.0, 900.0, 1.0])
    ukf, ekf = UnscentedFilter(model, x0, P0), ExtendedKalmanFilter(model, x0, P0)
    rng = np.random.default_rng(2)
    sensors = [(PositionSensor(5.0), np.zeros(4)), (PositionSensor(8.0), np.ones(4))]
    x = x0.copy()
    for k in range(1, 11):
        x = model.sample(x, 2.0, rng)
        ms = [Measurement(s, pv, s.sample(x, pv, rng), 2.0 * k, f"p{j}") for j, (s, pv) in
              enumerate(sensors)]  # fmt: skip
        if k == 4:
            ms[1] = Measurement(sensors[1][0], sensors[1][1], None, 2.0 * k, "p1")
        a, b = ukf.step(2.0 * k, ms), ekf.step(2.0 * k, ms)
        np.testing.assert_allclose(ukf.mean, ekf.mean, rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(ukf.cov, ekf.cov, rtol=1e-9, atol=1e-9)
        assert (a.n_detections, a.n_missed, a.dof) == (b.n_detections, b.n_missed, b.dof)
        assert a.nis == pytest.approx(b.nis, rel=1e-8)
        assert a.log_likelihood == pytest.approx(b.log_likelihood, rel=1e-10)
    assert ukf.time == ekf.time == 20.0 and np.all(np.isfinite(a.nis_per_measurement))


def test_registration_makes_the_name_valid_and_is_undone(ukf):
    assert filter_names() == ("ekf", "pf", "ukf")
    assert ukf.factory is make_ukf and not ukf.particle_based
    # Registering the same factory again changes nothing; another one under the name fails.
    assert register_filter("ukf", make_ukf, description=ukf.description) is ukf
    with pytest.raises(ValueError, match="registered already"):
        register_filter("ukf", lambda *args: None)
    for name in ("ekf", "pf"):  # built-in: neither replaced nor removed
        with pytest.raises(ValueError, match="registered already"):
            register_filter(name, make_ukf, replace=True)
        with pytest.raises(ValueError, match="not a registered, removable filter"):
            unregister_filter(name)
    with pytest.raises(ValueError, match="lower-case letters"):
        register_filter("UKF", make_ukf)
    with pytest.raises(ValueError, match="callable"):
        register_filter("ukf2", "make_ukf")
    # The schema's allowed values are the registry's.
    data = yaml.safe_load(without_plugins(SCENARIO))
    assert parse_scenario(data).tracker.filter == "ukf"
    data["tracker"]["filter"] = "srukf"
    with pytest.raises(ScenarioError, match="tracker.filter: must be one of 'ekf', 'pf' or 'ukf'"):
        parse_scenario(data)


def test_an_unregistered_filter_is_refused_with_the_allowed_values():
    assert "ukf" not in filter_names()
    with pytest.raises(ScenarioError, match="tracker.filter: must be one of 'ekf' or 'pf', got"):
        parse_scenario(yaml.safe_load(without_plugins(SCENARIO)))


def test_closed_loop_batch_with_the_ukf(ukf, tmp_path):
    """Six closed-loop runs (PCRLB planning from the UKF's track) against the EKF on the same
    seeds: the UKF's RMSE is within 10 % of the EKF's, both far below the prior's 50 m, its
    covariances are finite and positive definite at every epoch, and it is consistent (mean
    NEES near the state dimension 4)."""
    path = tmp_path / "ukf_bearings.yaml"
    path.write_text(without_plugins(SCENARIO))
    scenario = load_scenario(path)
    assert scenario.tracker.filter == "ukf"
    ukf_runs = run_batch(scenario, runs=6)
    ekf_runs = run_batch(with_tracker_overrides(scenario, filter="ekf"), runs=6)
    for u, e in (
        (ukf_runs.time_avg_rmse_x[0], ekf_runs.time_avg_rmse_x[0]),
        (ukf_runs.time_avg_rmse_y[0], ekf_runs.time_avg_rmse_y[0]),
    ):
        assert 1.0 < u < 15.0 and 1.0 < e < 15.0
        assert u == pytest.approx(e, rel=0.10)
    assert ukf_runs.time_avg_rmse_x != ekf_runs.time_avg_rmse_x  # not the EKF again
    nees = []
    for record in ukf_runs.records:
        x, covs = record.track_series()
        assert np.all(np.isfinite(covs))
        for P in covs:
            assert np.array_equal(P, P.T)
            assert np.linalg.eigvalsh(P)[0] > 0.0
        err = x[1:] - record.truth[1:, 0]
        nees += [float(d @ np.linalg.solve(P, d)) for d, P in zip(err, covs[1:], strict=True)]
    assert 2.0 < np.mean(nees) < 6.0
    assert len(ukf_runs.records[0].decisions) == 20  # planned from the UKF's track each epoch


def test_particle_based_filters_feed_the_planner_samples():
    """A filter registered ``particle_based`` is a PF for the tracker and the schema: here the
    built-in PF's factory under another name gives the very same track and planner samples,
    and the particle rules name it."""
    register_filter("pf_copy", filter_kind("pf").factory, particle_based=True)
    try:
        data = yaml.safe_load(without_plugins(SCENARIO))
        data["tracker"] = {"filter": "pf", "particles": 500, "planner_samples": 100}
        pf = parse_scenario(data)
        data["tracker"]["filter"] = "pf_copy"
        copy = parse_scenario(data)
        (a,) = build_tracker(pf, np.random.default_rng(4)).snapshot().tracks
        tracks = build_tracker(copy, np.random.default_rng(4)).snapshot()
        (b,) = tracks.tracks
        assert tracks.filter_kind == "pf_copy" and b.particle_count == 500
        np.testing.assert_array_equal(a.samples, b.samples)
        np.testing.assert_array_equal(a.mean, b.mean)
        data["tracker"]["particles"] = 50
        with pytest.raises(ScenarioError, match="must be >= 100 with filter 'pf_copy'"):
            parse_scenario(data)
        # A factory that does not return a TrackingFilter is refused by name.
        register_filter("broken", lambda model, x0, P0, config, rng: object())
        model = NearlyConstantVelocity(q=0.05)
        with pytest.raises(ValueError, match=r"filter 'broken': its factory returned an? "):
            make_filter("broken", model, np.zeros(4), np.eye(4), None, np.random.default_rng())
    finally:
        for name in ("pf_copy", "broken"):
            if name in filter_names():
                unregister_filter(name)


def test_a_scenario_file_brings_its_filter_through_plugins(plugin_folder, capsys):
    """`activetrack batch` on the scenario of docs/extending.md: the file names the plugin
    module (docs/extending.md's my_filters.py), which registers ``ukf`` when the scenario is
    loaded; the forked Monte Carlo workers (--jobs 2) know it too."""
    path = plugin_folder / "ukf_bearings.yaml"
    path.write_text(SCENARIO)
    assert "ukf" not in filter_names()
    out = plugin_folder / "summary.json"
    rc = cli_main(["batch", str(path), "--runs", "2", "--jobs", "2", "--json", str(out)])
    assert rc == 0, capsys.readouterr().err
    assert filter_kind("ukf").factory.__module__ == "my_filters"
    summary = json.loads(out.read_text())
    assert summary["runs"] == 2 and 1.0 < summary["time_avg_rmse_x"][0] < 15.0
    assert load_scenario(path).tracker.filter == "ukf"  # a second load imports nothing again


def test_a_plugin_that_fails_to_import_is_one_clear_error(plugin_folder, capsys):
    (plugin_folder / "bad_filters.py").write_text(
        "from activetrack.filters import filter_kind, register_filter\n"
        "register_filter('ekf', filter_kind('pf').factory)\n"
    )
    path = plugin_folder / "bad.yaml"
    path.write_text(SCENARIO.replace("plugins: [my_filters]", "plugins: [my_filters, bad_filters]"))
    assert cli_main(["batch", str(path)]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"error: {path}: plugins[1]: cannot import module 'bad_filters' (ValueError: filter "
        "'ekf' is registered already; unregister_filter it first)\n"
    )
