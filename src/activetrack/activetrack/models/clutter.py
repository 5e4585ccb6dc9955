"""A sensor in clutter: :class:`ClutteredSensor` wraps any sensor model with

- a field of view: a bearing sector ``fov_width`` wide centred ``fov_centre`` off the
  platform's heading (its pv velocity), or all around; a beam (``beam_width``) is pointed each
  epoch (:meth:`field_of_view` with ``pointing``); detection with ``pd`` inside it and the
  detection ranges;
- Poisson false alarms, mean ``lambda V`` per scan (``lambda = clutter_density``), uniform over
  the field of view in measurement space (V: sector width [rad], times ``r_max - r_min`` [m]
  for a range-bearing sensor);
- Fisher information: ``H^T R^-1 H`` times the information reduction factor
  ``q(Pd, lambda sqrt(det R), g, dim_z)`` (:mod:`activetrack.models.irf`) in place of the pd
  of Hernandez eq. 8, zero outside the field of view (no clutter, wide gate: q = pd);
- for a planner's expected update of a track N(x, P) (:meth:`planned_information_factor`),
  with ``clutter_gate`` ``innovation``, the q of the tracker's actual gate: the same integral
  in the space whitened by the innovation covariance ``S = H P H^T + R``, whose false alarms
  have the density ``lambda sqrt(det S)`` (the modified Riccati equation of the PDA, Kershaw &
  Evans, "Optimal waveform selection for tracking systems", IEEE T-IT 40(5), 1994: its
  reduction depends on lambda V_gate, V_gate ~ sqrt(det S)). A track whose prediction is wide
  against R (a close target seen in angle, an uncertain track) gates more clutter and learns
  less from a scan; ``measurement`` (the default) keeps the one q of R.

Every other member is the wrapped sensor's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.models.base import InformationKernel, SensorModel
from activetrack.models.fov import FieldOfView
from activetrack.models.irf import information_reduction_factor, information_reduction_factors

__all__ = [
    "CLUTTER_GATES",
    "ClutteredSensor",
    "fov_volume",
    "has_clutter_model",
    "starts_tracks",
]

_TWO_PI = 2.0 * math.pi

# Where a planner's expected update takes the clutter density of the IRF from (module docstring).
CLUTTER_GATES = ("measurement", "innovation")

# A target 1 km ahead of a sensor at the origin: where the capabilities below are probed.
_PROBE_TARGET = np.array([1000.0, 0.0, 0.0, 0.0])
_ORIGIN = np.zeros(4)


def has_clutter_model(sensor: SensorModel) -> bool:
    """Whether ``sensor`` models clutter over a field of view (its ``clutter_volume`` is not
    None: it knows its measurement space)."""
    return sensor.clutter_volume(FieldOfView()) is not None


def starts_tracks(sensor: SensorModel) -> bool:
    """Whether one detection of ``sensor`` fixes a position (its ``inverse_position`` of a
    measurement is not None), so that it can start a track."""
    z = np.asarray(sensor.measure(_PROBE_TARGET, _ORIGIN), dtype=float).reshape(-1)
    return sensor.inverse_position(z, _ORIGIN) is not None


def fov_volume(sensor: SensorModel, width: float, r_min: float, r_max: float) -> float:
    """Volume of ``sensor``'s field of view in its measurement space (its ``clutter_volume``
    of the sector ``width`` [rad] and ranges [r_min, r_max] [m]; infinite for an unbounded
    range where the range is measured); ValueError for a sensor without a clutter model."""
    return ClutteredSensor(sensor).clutter_volume(FieldOfView(0.0, width, r_min, r_max))


@dataclass(frozen=True)
class ClutteredSensor:
    """``base`` in clutter of ``clutter_density`` (per unit of z) within a field of view;
    ``gate_sigmas`` the association gate (the IRF's g). ``gated`` False: every detection is the
    one target's (known association), and the information factor is ``pd`` itself.
    ``clutter_gate``: the gate of :meth:`planned_information_factor` (:data:`CLUTTER_GATES`)."""

    base: SensorModel
    clutter_density: float = 0.0
    gate_sigmas: float = 3.5
    fov_centre: float = 0.0
    fov_width: float | None = None
    beam_width: float | None = None
    gated: bool = True
    clutter_gate: str = "measurement"

    def __post_init__(self) -> None:
        if self.clutter_gate not in CLUTTER_GATES:
            raise ValueError(
                f"clutter_gate must be one of {CLUTTER_GATES}, got {self.clutter_gate!r}"
            )

    def __getattr__(self, name: str) -> Any:
        # Everything not defined here (kind, R, measure, residual, ...) is the base sensor's.
        if name == "base":
            raise AttributeError(name)
        return getattr(self.base, name)

    @property
    def steerable(self) -> bool:
        return self.beam_width is not None

    @property
    def information_factor(self) -> float:
        """The IRF ``q`` that replaces ``pd`` in J_Z (cached in :mod:`activetrack.models.irf`);
        ``pd`` itself for a sensor whose detections are not gated."""
        if not self.gated:
            return float(self.base.pd)
        R = np.atleast_2d(np.asarray(self.base.R, dtype=float))
        whitened = self.clutter_density * math.sqrt(float(np.linalg.det(R)))
        return information_reduction_factor(
            float(self.base.pd), whitened, self.gate_sigmas, int(self.base.dim_z)
        )

    def planned_information_factor(
        self, x: ArrayLike, sensor_pv: ArrayLike, P: ArrayLike
    ) -> float | FloatArray:
        """The IRF ``q`` of a planned look at a track N(``x`` ``(4,)``, ``P`` ``(..., 4, 4)``)
        from ``sensor_pv`` ``(..., 4)``: :attr:`information_factor` (``clutter_gate``
        ``measurement``, no clutter, or no gate), else ``q(Pd, lambda sqrt(det S), g,
        dim_z)`` with ``S = H P H^T + R``, H the Jacobian at x ``(...)``."""
        if self.clutter_gate == "measurement" or not self.gated or self.clutter_density <= 0.0:
            return self.information_factor
        H = np.asarray(self.base.jacobian(x, sensor_pv), dtype=float)
        R = np.atleast_2d(np.asarray(self.base.R, dtype=float))
        S = H @ np.asarray(P, dtype=float) @ np.swapaxes(H, -1, -2) + R
        whitened = self.clutter_density * np.sqrt(np.linalg.det(S))
        return information_reduction_factors(
            float(self.base.pd), whitened, self.gate_sigmas, int(self.base.dim_z)
        )

    def field_of_view(self, sensor_pv: ArrayLike, pointing: float | None = None) -> FieldOfView:
        """Where the sensor looks from ``sensor_pv`` ``(4,)``: the beam's sector around
        ``pointing`` [rad, world frame] for a steerable sensor (required), else the fixed
        sector off the platform's heading, else all around; ranges [r_min, r_max]."""
        s = np.asarray(sensor_pv, dtype=float)
        r_min, r_max = float(self.base.r_min), float(self.base.r_max)
        if self.beam_width is not None:
            if pointing is None or not math.isfinite(pointing):
                raise ValueError("pointing: a steerable beam needs a finite bearing")
            return FieldOfView(float(pointing), self.beam_width, r_min, r_max)
        if self.fov_width is not None:
            heading = math.atan2(s[3], s[1])
            centre = math.remainder(heading + self.fov_centre, _TWO_PI)
            return FieldOfView(centre, self.fov_width, r_min, r_max)
        return FieldOfView(0.0, _TWO_PI, r_min, r_max)

    def clutter_volume(self, fov: FieldOfView) -> float:
        """The base sensor's ``clutter_volume`` (rad, m rad, ...); ValueError without one."""
        volume = self.base.clutter_volume(fov)
        if volume is None:
            raise ValueError(f"sensor kind {self.base.kind!r} has no clutter model")
        return float(volume)

    def detect(
        self,
        target_pv: ArrayLike,
        sensor_pv: ArrayLike,
        rng: np.random.Generator,
        fov: FieldOfView | None = None,
    ) -> np.ndarray:
        """Whether the target is detected: inside the detection ranges and the field of view
        ``fov`` (None: all around), and a Bernoulli(pd) draw, one per state whether inside or
        not (the draws do not depend on where the target is), bool ``(...)``."""
        inside = np.asarray(self.base.in_range(target_pv, sensor_pv), dtype=bool)
        if fov is not None and not fov.all_around:
            inside = inside & fov.contains(np.asarray(target_pv), np.asarray(sensor_pv))
        return inside & (rng.random(inside.shape) < float(self.base.pd))

    def sample_clutter(self, fov: FieldOfView, rng: np.random.Generator) -> FloatArray:
        """Poisson(lambda V) false alarms uniform over ``fov`` in measurement space,
        ``(m, dim_z)`` (the base sensor's ``uniform_measurements``). Draws the count, then the
        points, from ``rng``; nothing without clutter."""
        d = int(self.base.dim_z)
        if self.clutter_density <= 0.0:
            return np.empty((0, d))
        m = int(rng.poisson(self.clutter_density * self.clutter_volume(fov)))
        u = rng.random((m, d))
        return np.asarray(self.base.uniform_measurements(u, fov), dtype=float).reshape(m, d)

    def fisher_information(
        self,
        target_samples: FloatArray,
        sensor_pv: FloatArray,
        kinematics_jacobian: FloatArray | None = None,
    ) -> FloatArray:
        """``q / pd`` times the base sensor's J_Z (Hernandez eq. 8 with the IRF in place of
        pd), zero for samples outside a fixed field of view (a beam is assumed on target)."""
        J = self.base.fisher_information(target_samples, sensor_pv, kinematics_jacobian)
        scale = self.information_factor / float(self.base.pd)
        if self.fov_width is None:
            return scale * J
        # Outside the sector a sample adds nothing: recompute the mean over the inside ones.
        X = np.asarray(target_samples, dtype=float)
        S = np.asarray(sensor_pv, dtype=float)
        heading = np.arctan2(S[..., 3], S[..., 1])
        dx = X[:, 0] - S[..., 0, None]
        dy = X[:, 2] - S[..., 2, None]
        off = np.angle(np.exp(1j * (np.arctan2(dy, dx) - heading[..., None] - self.fov_centre)))
        inside = np.abs(off) <= 0.5 * self.fov_width  # (..., M)
        if np.all(inside):
            return scale * J
        out = np.zeros_like(J)
        flat_S = S.reshape(-1, 4)
        flat_in = inside.reshape(-1, X.shape[0])
        flat_out = out.reshape(-1, *J.shape[-2:])
        M = X.shape[0]
        for i, (s, keep) in enumerate(zip(flat_S, flat_in, strict=True)):
            if keep.any():
                K = None if kinematics_jacobian is None else kinematics_jacobian[keep]
                part = self.base.fisher_information(X[keep], s, K)
                flat_out[i] = part * keep.sum() / M
        return scale * out

    def information_kernel(self) -> InformationKernel | None:
        """The base sensor's compiled J_Z times ``q / pd``; None with a fixed field of view (its
        per-sample mask is the numpy form's) or a base without a kernel. Defined here so that
        forwarding unknown members never hands out the base's kernel without the IRF."""
        get = getattr(self.base, "information_kernel", None)
        kernel = None if get is None or self.fov_width is not None else get()
        if kernel is None:
            return None
        scale = self.information_factor / float(self.base.pd)
        return lambda X, S: scale * kernel(X, S)

    @classmethod
    def wrap(
        cls, base: SensorModel, cfg: Any, gate_sigmas: float, gated: bool = True
    ) -> ClutteredSensor:
        """From a validated ``sensors:`` entry ``cfg`` (its clutter and field-of-view fields)."""
        return cls(
            base,
            float(cfg.clutter_density),
            float(gate_sigmas),
            float(cfg.fov_centre),
            cfg.fov_width,
            cfg.beam_width,
            gated,
        )
