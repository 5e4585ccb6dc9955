"""ekf_over_runs is ExtendedKalmanFilter run once per Monte Carlo run, batched."""

from __future__ import annotations

import numpy as np
import pytest

from activetrack.filters import ExtendedKalmanFilter, Measurement, ekf_over_runs
from activetrack.models import BearingSensor, NearlyConstantVelocity, RangeBearingSensor
from activetrack.models.motion import ConstantTurn

SENSOR_PV = np.array([-50.0, 0.0, 20.0, 0.0])


@pytest.mark.parametrize(
    "model, sensor",
    [
        (NearlyConstantVelocity(0.05), BearingSensor(0.02)),
        (NearlyConstantVelocity(0.05), RangeBearingSensor(2.0, 0.02)),
        (ConstantTurn(omega=0.05, q=0.05), RangeBearingSensor(2.0, 0.02)),
    ],
)
def test_equals_one_library_ekf_per_run(model, sensor):
    rng = np.random.default_rng(4)
    runs, steps, dt = 4, 25, 1.0
    x_true = np.array([100.0, 1.0, 50.0, -0.5])
    P0 = np.diag([25.0, 0.25, 25.0, 0.25])
    x0 = x_true + rng.standard_normal((runs, 4)) * np.sqrt(np.diag(P0))
    truth = [x_true]
    for _ in range(steps):
        truth.append(model.propagate(truth[-1], dt))
    z = np.stack(
        [[sensor.sample(truth[k + 1], SENSOR_PV, rng) for _ in range(runs)] for k in range(steps)]
    )  # (K, M, dim_z)
    means, covs = ekf_over_runs(model, sensor, SENSOR_PV, x0, P0, z, dt)
    assert means.shape == (steps, runs, 4) and covs.shape == (steps, runs, 4, 4)
    for r in range(runs):
        ekf = ExtendedKalmanFilter(model, x0[r], P0)
        for k in range(steps):
            t = (k + 1) * dt
            ekf.step(t, [Measurement(sensor, SENSOR_PV, z[k, r], t)])
            np.testing.assert_allclose(means[k, r], ekf.mean, rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(covs[k, r], ekf.cov, rtol=1e-9, atol=1e-12)
    # Joseph form keeps every covariance symmetric positive definite.
    assert np.all(np.linalg.eigvalsh(covs) > 0.0)
    np.testing.assert_array_equal(covs, np.swapaxes(covs, -1, -2))
    means_only, none = ekf_over_runs(model, sensor, SENSOR_PV, x0, P0, z, dt, keep_cov=False)
    assert none is None
    np.testing.assert_array_equal(means_only, means)
