"""A sensor kind and a filter that live only here, for the plugin tests (tests/core and
tests/ros): registered with the public registries, they must run wherever the built-in ones do,
including a scene of several targets with clutter and steerable beams.

- ``position_fix``: z = (x, y) - (x_s, y_s) + v, v ~ N(0, sigma^2 I), a sensor that measures
  the target's offset from the platform (a GPS-aided radar's fix). Its clutter model is uniform
  over the field of view's area (a sector of the annulus r_min <= r <= r_max), so its clutter
  density is per m^2; one detection fixes the position, so it starts tracks.
- ``pda_kf``: a Kalman filter for linear motion models that linearises any sensor at the
  prediction (``sensor.linearize``) and takes uncertain scans through ``update_pda``, the PDA
  update written from Bar-Shalom, Daum & Huang, "The probabilistic data association filter",
  IEEE Control Systems Magazine 29(6), 2009, eq. 27-32. Its factory takes ``t0``, so the
  tracker can start it from a detection after epoch 0.

Nothing is registered on import (test modules are imported while pytest collects): call
:func:`register` and :func:`unregister` (the ``plugins`` fixture of tests/core/test_plugins.py),
or name :mod:`plugin_registration` in a scenario's ``plugins:`` (a process that loads the file,
e.g. a ROS node, then registers both; tests/ must be on its import path).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, ClassVar, Literal

import numpy as np
from pydantic import Field

from activetrack.filters import (
    Measurement,
    UpdateInfo,
    filter_names,
    register_filter,
    unregister_filter,
)
from activetrack.filters.measurement import (
    check_measurement_times,
    check_predict_time,
    pda_weights,
)
from activetrack.models import GaussianSensor
from activetrack.models.fov import FieldOfView
from activetrack.scenarios import (
    SensorConfigBase,
    register_sensor,
    registered_kinds,
    unregister_sensor,
)

SENSOR_KIND = "position_fix"
FILTER_NAME = "pda_kf"

# The t0 of every filter the factory built in this process, in order (what a test inspects).
FACTORY_T0: list[float] = []


# --- the sensor ----------------------------------------------------------------------------


@dataclass(frozen=True)
class PositionFixSensor(GaussianSensor):
    """z = (x - x_s, y - y_s) + v, v ~ N(0, sigma^2 I) [m]."""

    sigma: float
    pd: float = 1.0
    r_min: float = 0.0
    r_max: float = math.inf

    kind: ClassVar[str] = SENSOR_KIND
    components: ClassVar[tuple[str, ...]] = ("dx", "dy")

    def __post_init__(self) -> None:
        if not (math.isfinite(self.sigma) and self.sigma > 0):
            raise ValueError(f"sigma must be finite and > 0, got {self.sigma!r}")
        self.validate_detection()

    @property
    def R(self) -> np.ndarray:
        return self.sigma**2 * np.eye(2)

    def measure(self, target_pv, sensor_pv) -> np.ndarray:
        d = np.asarray(target_pv, dtype=float) - np.asarray(sensor_pv, dtype=float)
        return d[..., [0, 2]]

    def jacobian(self, target_pv, sensor_pv) -> np.ndarray:
        shape = np.broadcast_shapes(np.shape(target_pv), np.shape(sensor_pv))[:-1]
        H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
        return np.broadcast_to(H, (*shape, 2, 4))

    def clutter_volume(self, fov: FieldOfView) -> float:
        """The area [m^2] of the field of view's sector of the annulus r_min..r_max (infinite
        without a maximum range: the scenario rules then refuse clutter for it)."""
        return 0.5 * min(fov.width, 2.0 * math.pi) * (fov.r_max**2 - fov.r_min**2)

    def uniform_measurements(self, u: np.ndarray, fov: FieldOfView) -> np.ndarray:
        """Points uniform over that area from unit draws ``u`` ``(m, 2)``: r^2 uniform on
        [r_min^2, r_max^2], the bearing uniform across the sector."""
        u = np.asarray(u, dtype=float).reshape(-1, 2)
        r = np.sqrt(fov.r_min**2 + u[:, 0] * (fov.r_max**2 - fov.r_min**2))
        b = fov.centre + (u[:, 1] - 0.5) * min(fov.width, 2.0 * math.pi)
        return np.stack([r * np.cos(b), r * np.sin(b)], axis=-1)

    def inverse_position(self, z, sensor_pv) -> tuple[np.ndarray, np.ndarray]:
        """The fix itself: (x_s + z_0, y_s + z_1), covariance R."""
        s = np.asarray(sensor_pv, dtype=float)
        return s[[0, 2]] + np.asarray(z, dtype=float), self.R


class PositionFixConfig(SensorConfigBase):
    kind: Literal["position_fix"]
    sigma: Annotated[float, Field(gt=0, le=1e4, allow_inf_nan=False)]  # m


# --- the filter ----------------------------------------------------------------------------


class PdaKalmanFilter:
    """Kalman filter for a linear motion model (``transition_matrix``), with each sensor
    linearised at the prediction; ``update_pda`` for scans of uncertain origin."""

    def __init__(self, model, x0, P0, t0: float = 0.0):
        if not model.is_linear:
            raise ValueError("model: pda_kf needs linear dynamics (is_linear)")
        self.model = model
        self._x = np.array(x0, dtype=float)
        self._P = np.array(P0, dtype=float)
        self._t = float(t0)
        self.pda_updates = 0

    @property
    def time(self) -> float:
        return self._t

    @property
    def mean(self) -> np.ndarray:
        return self._x.copy()

    @property
    def cov(self) -> np.ndarray:
        return self._P.copy()

    def predict(self, t: float) -> None:
        t = check_predict_time(t, self._t)
        if t > self._t:
            F = self.model.transition_matrix(t - self._t)
            self._x = F @ self._x
            self._P = F @ self._P @ F.T + self.model.process_noise(t - self._t)
            self._P = 0.5 * (self._P + self._P.T)
        self._t = t

    def _linearised(self, m: Measurement, Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """H ``(d, n)`` at the prediction and the residuals ``(m, d)`` of the detections Z."""
        pv = self.model.kinematics(self._x)
        H = None
        residuals = []
        for z in Z:
            lin = m.sensor.linearize(pv, m.sensor_state, z)
            H = lin.H @ self.model.kinematics_jacobian(self._x)
            residuals.append(lin.nu)
        return H, np.array(residuals)

    def _gain(self, H: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The innovation covariance S and the gain K = P H^T S^-1 (a solve, not an inverse)."""
        S = H @ self._P @ H.T + R
        K = np.linalg.solve(S, H @ self._P).T
        return S, K

    def update(self, measurements: Sequence[Measurement]) -> UpdateInfo:
        """Each detection in turn (Joseph form); a look without one changes nothing."""
        check_measurement_times(measurements, self._t)
        nis = []
        for m in measurements:
            if m.z is None:
                continue
            H, nu = self._linearised(m, np.atleast_2d(m.z))
            R = np.asarray(m.sensor.R, dtype=float)
            S, K = self._gain(H, R)
            nis.append(float(nu[0] @ np.linalg.solve(S, nu[0])))
            self._x = self._x + K @ nu[0]
            A = np.eye(len(self._x)) - K @ H
            self._P = A @ self._P @ A.T + K @ R @ K.T
        return UpdateInfo(
            time=self._t,
            n_detections=len(nis),
            n_missed=len(measurements) - len(nis),
            nis=sum(nis) if nis else math.nan,
            sensor_ids=tuple(m.sensor_id for m in measurements),
        )

    def update_pda(self, measurements: Sequence[Measurement], beta) -> UpdateInfo:
        """The PDA update with the association probabilities ``beta`` ``(m + 1,)``: the
        combined residual nu = sum_j beta_j nu_j, x += K nu, and
        P = beta_0 P + (1 - beta_0) P_c + K (sum_j beta_j nu_j nu_j^T - nu nu^T) K^T with
        P_c the Joseph-form update of one certain detection."""
        check_measurement_times(measurements, self._t)
        b = pda_weights(measurements, beta)
        self.pda_updates += 1
        if b[0] < 1.0:
            Z = np.stack([np.asarray(m.z, dtype=float) for m in measurements])
            H, nus = self._linearised(measurements[0], Z)
            R = np.asarray(measurements[0].sensor.R, dtype=float)
            _, K = self._gain(H, R)
            nu = b[1:] @ nus
            A = np.eye(len(self._x)) - K @ H
            P_c = A @ self._P @ A.T + K @ R @ K.T
            spread = (nus.T * b[1:]) @ nus - np.outer(nu, nu)
            self._x = self._x + K @ nu
            self._P = b[0] * self._P + (1.0 - b[0]) * P_c + K @ spread @ K.T
            self._P = 0.5 * (self._P + self._P.T)
        return UpdateInfo(
            time=self._t,
            n_detections=len(measurements),
            sensor_ids=tuple(m.sensor_id for m in measurements),
        )

    def step(self, t: float, measurements: Sequence[Measurement]) -> UpdateInfo:
        self.predict(t)
        return self.update(measurements)


def make_pda_kf(model, x0, P0, config, rng, t0: float = 0.0) -> PdaKalmanFilter:
    """The registry's factory: no option of the tracker block, no random draws; ``t0`` is
    the time of (x0, P0)."""
    FACTORY_T0.append(float(t0))
    return PdaKalmanFilter(model, x0, P0, t0)


# --- registration --------------------------------------------------------------------------


def register() -> None:
    """Register the sensor kind and the filter (again: a no-op)."""
    register_sensor(PositionFixSensor, PositionFixConfig)
    register_filter(FILTER_NAME, make_pda_kf, description="Kalman filter with PDA (a test's)")


def unregister() -> None:
    """Take both away again (those registered)."""
    if SENSOR_KIND in registered_kinds():
        unregister_sensor(SENSOR_KIND)
    if FILTER_NAME in filter_names():
        unregister_filter(FILTER_NAME)


# A scene of three targets (t2 dies, t3 is born late) with clutter and steerable beams, seen
# only by position_fix sensors and tracked by pda_kf (tests/core/test_plugins.py runs it
# through run_batch, tests/ros/test_plugins_graph.py through the graph and retrack).
SCENE = """\
name: {name}
seed: 5
plugins: [plugin_registration]
dt: 2.0
steps: {steps}
targets:
  - {{id: t1, motion: {{model: ncv, q: 0.5}},
     prior: {{mean: [0.0, 10.0, 1000.0, 0.0], var: [400.0, 4.0, 400.0, 4.0]}}}}
  - {{id: t2, motion: {{model: ncv, q: 0.5}}, death: {death},
     prior: {{mean: [1500.0, -5.0, -500.0, 8.0], var: [400.0, 4.0, 400.0, 4.0]}}}}
  - {{id: t3, motion: {{model: ncv, q: 0.5}}, birth: {birth},
     prior: {{mean: [-1000.0, 6.0, -1500.0, 6.0], var: [400.0, 4.0, 400.0, 4.0]}}}}
platforms:
  - id: p1
    initial_state: [-3000.0, 30.0, 0.0, 0.0]
    controllable: true
    limits: {{dpsi_max: 0.3, dv_max: 5.0, v_min: 20.0, v_max: 40.0}}
    sensors:
      - {{id: surv, kind: position_fix, sigma: 40.0, pd: 0.9, r_min: 50.0, r_max: 8000.0,
         clutter_density: 1.0e-8}}
      - {{id: beam1, kind: position_fix, sigma: 8.0, pd: 0.9, r_min: 50.0, r_max: 8000.0,
         beam_width: 0.15, clutter_density: 1.0e-7}}
  - id: p2
    initial_state: [3000.0, 0.0, 3000.0, 0.0]
    sensors:
      - {{id: beam2, kind: position_fix, sigma: 8.0, pd: 0.9, r_min: 50.0, r_max: 8000.0,
         beam_width: 0.15, clutter_density: 1.0e-7}}
tracker:
  filter: pda_kf
  tracks: {{gate_sigmas: 3.5, confirm_m: 2, confirm_n: 3, delete_misses: 4, init_speed_std: 20.0}}
planner:
  cost: pcrlb
  criterion: b_k
  search: quadrant
  mc_samples: {mc_samples}
  targets: {{aggregate: weighted_sum, assignment: mre}}
evaluation: {{cutoff: 300.0, order: 2, alpha: 2}}
"""


def scene_yaml(name: str, steps: int, death: int, birth: int, mc_samples: int) -> str:
    """The scene's file text with its length, t2's death, t3's birth and the planner's
    samples."""
    return SCENE.format(name=name, steps=steps, death=death, birth=birth, mc_samples=mc_samples)
