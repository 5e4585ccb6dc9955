"""A sensor kind and a filter defined only in a test module (tests/plugins_for_tests.py: the
``position_fix`` sensor with its own clutter model, the ``pda_kf`` filter with ``update_pda``
and a factory that takes ``t0``) run a scene of three targets, one born late and one dying,
with clutter and steerable beams, through ``run_batch`` (issue 24: plugins everywhere).

The scenario rules ask the registries (a kind's clutter model and track starts, a filter's
``update_pda``), so the scene's file loads as written.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import plugins_for_tests as plugins
import pytest

from activetrack.closed_loop.batch import run_batch
from activetrack.closed_loop.components import scene_sensors
from activetrack.filters import filter_names
from activetrack.scenarios import load_scenario, registered_kinds

SCENARIO = plugins.scene_yaml("plugin_scene", steps=16, death=12, birth=4, mc_samples=100)


@pytest.fixture
def scenario_file(tmp_path):
    """The scene's file, the plugins registered for the test (the scenario's ``plugins:``
    imports plugin_registration, which registers them) and taken away afterwards."""
    path = tmp_path / "plugin_scene.yaml"
    path.write_text(SCENARIO)
    yield path
    plugins.unregister()
    sys.modules.pop("plugin_registration", None)


def test_the_scenario_rules_accept_the_plugins(scenario_file):
    scenario = load_scenario(scenario_file)
    assert scenario.tracker.filter == plugins.FILTER_NAME


def test_plugin_sensor_and_filter_run_a_batch_with_clutter_and_beams(scenario_file, monkeypatch):
    scenario = load_scenario(scenario_file)
    assert "plugin_registration" in sys.modules  # the file's plugins: registered them
    pda_calls = []
    update_pda = plugins.PdaKalmanFilter.update_pda

    def counted(self, measurements, beta):
        pda_calls.append(len(measurements))
        return update_pda(self, measurements, beta)

    monkeypatch.setattr(plugins.PdaKalmanFilter, "update_pda", counted)
    plugins.FACTORY_T0.clear()
    summary = run_batch(scenario, runs=2, jobs=1)  # in this process: the counts are seen

    # JPDA through the filter's update_pda; GOSPA finite at every epoch of both runs.
    assert summary.association == "jpda" and summary.target_ids == ("t1", "t2", "t3")
    assert len(pda_calls) > 50
    assert np.isfinite(summary.gospa_t).all() and np.isfinite(summary.run_gospa).all()
    assert 0.0 < summary.mean_gospa < 300.0 * math.sqrt(3)
    # Every target held most of its life, the late one by a track the plugin sensor's
    # detections started, its filter built at the detection's time (t0 > 0) by the factory.
    assert min(summary.held_fraction) > 0.5
    assert (
        np.isfinite(summary.time_avg_rmse_x).all() and np.isfinite(summary.time_avg_bound_x).all()
    )
    late = sorted({t0 for t0 in plugins.FACTORY_T0 if t0 > 0.0})
    assert late and all(t0 % scenario.dt == 0.0 and t0 <= 32.0 for t0 in late)
    for record, ev in zip(summary.records, summary.evaluations, strict=True):
        # The beams were pointed at tracks; the bound is the plugin sensor's, finite while alive.
        assert any(b.track_id > 0 for d in record.decisions for b in d.beams)
        assert np.array_equal(np.isfinite(ev.bound).all(axis=(2, 3)), ev.alive)
        assert any(t.origin == "" for ts in record.tracks for t in ts.confirmed)
    _check_clutter(scenario, summary.records)


def _check_clutter(scenario, records):
    """The false alarms come from the plugin's clutter model: inside each scan's field of view,
    lambda V per scan on average (V the area of the sector of the annulus, per m^2)."""
    sensors = {sid: sensor for sid, (_, sensor) in scene_sensors(scenario).items()}
    counts, expected = [], []
    for record in records:
        for scans, truths in zip(record.scans, record.scan_truth, strict=True):
            for scan, truth in zip(scans, truths, strict=True):
                clutter = scan.Z[[label == "" for label in truth.labels]]
                pv = np.zeros((len(clutter), 4))
                pv[:, [0, 2]] = scan.sensor_pv[[0, 2]] + clutter  # z is the offset
                assert scan.fov.contains(pv, scan.sensor_pv).all()
                sensor = sensors[scan.sensor_id]
                width = min(scan.fov.width, 2 * math.pi)
                area = 0.5 * width * (sensor.r_max**2 - sensor.r_min**2)
                counts.append(len(clutter))
                expected.append(sensor.clutter_density * area)
    # Poisson: the mean of ~96 scans within 4 standard errors of the expected mean.
    n, mean = len(counts), float(np.mean(expected))
    assert abs(np.mean(counts) - mean) < 4.0 * math.sqrt(mean / n)
    assert mean == pytest.approx((2.0106 + 2 * 0.48) / 3, rel=1e-3)  # surv, beam1, beam2


def test_the_plugin_module_registers_nothing_on_import():
    """pytest imports test modules while collecting: a registration on import would change
    every later test's registered names."""
    assert plugins.SENSOR_KIND not in registered_kinds()
    assert plugins.FILTER_NAME not in filter_names()
    assert Path(plugins.__file__).parent.name == "tests"  # where tests/ros finds it too
