"""A test-only linear sensor shared by the filter tests: z = (x_t - x_s, y_t - y_s) + v, so a
Kalman filter is exact on it (analytic references for the EKF, the PF and the PDA/JPDA)."""

import math
from dataclasses import dataclass

import numpy as np

from activetrack.models.base import GaussianSensor


@dataclass(frozen=True)
class LinearPositionSensor(GaussianSensor):
    """Test-only linear sensor: z = (x_t - x_s, y_t - y_s) + v, v ~ N(0, sigma^2 I)."""

    sigma: float
    pd: float = 1.0
    r_min: float = 0.0
    r_max: float = math.inf
    kind = "position"
    components = ("x", "y")
    dim_z = 2
    H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])

    @property
    def R(self):
        return self.sigma**2 * np.eye(2)

    def measure(self, target_pv, sensor_pv):
        d = np.asarray(target_pv, float) - np.asarray(sensor_pv, float)
        return np.stack([d[..., 0], d[..., 2]], axis=-1)

    def jacobian(self, target_pv, sensor_pv):
        d = np.asarray(target_pv, float) - np.asarray(sensor_pv, float)
        return np.broadcast_to(self.H, (*d.shape[:-1], 2, 4)).copy()

    def residual(self, z, zhat):
        return np.asarray(z, float) - np.asarray(zhat, float)

    def in_range(self, target_pv, sensor_pv):
        d = np.asarray(target_pv, float) - np.asarray(sensor_pv, float)
        r = np.hypot(d[..., 0], d[..., 2])
        return (r >= self.r_min) & (r <= self.r_max)

    def sample(self, target_pv, sensor_pv, rng):
        h = self.measure(target_pv, sensor_pv)
        return h + self.sigma * rng.standard_normal(h.shape)
