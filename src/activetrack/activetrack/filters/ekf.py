"""Extended Kalman filter for any motion model and any mix of sensors.

Prediction (Valverde eq. 2-4, Ramdaras eq. 14-15)::

    x_k|k-1 = f(x_k-1|k-1, dt)                 model.propagate
    P_k|k-1 = F P_k-1|k-1 F^T + Q              F = model.jacobian at x_k-1|k-1

Update, one detection at a time (Ramdaras eq. 16-22, Valverde eq. 5-9)::

    nu = z - h(x)        angle entries wrapped by sensor.residual   (eq. 18)
    S  = H P H^T + R                                                 (eq. 17)
    K  = P H^T S^-1      by a linear solve, not an explicit inverse  (eq. 20)
    x  = x + K nu                                                    (eq. 21)
    P  = (I - K H) P (I - K H)^T + K R K^T    Joseph form            (eq. 22)

with h, H and nu from the sensor's ``linearize`` (H chained with ``kinematics_jacobian``):
filterpy's ``ExtendedKalmanFilter`` equations (tested to 1e-9) in plain numpy, or compiled with
``ACTIVETRACK_KERNELS=compiled`` (equal to round-off).

Several detections per step are processed sequentially, each linearised at the state the ones
before it updated (exactly the stacked update for a linear model; the NIS add up to a
chi-square of the summed dimension). A missed detection (``z is None``) leaves the prediction
untouched: Ramdaras sec. 2 skips the update ("nothing seen" would shrink P with eq. 19's
nu = 0 in eq. 22).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_finite, require_spd
from activetrack.filters.jpda import pda_residuals, pda_update, pda_update_many
from activetrack.filters.measurement import (
    Measurement,
    UpdateInfo,
    check_measurement_times,
    check_predict_time,
    check_prior,
    pda_probabilities,
    pda_weights,
)
from activetrack.kernels import ekf_kernels
from activetrack.models.base import MotionModel, as_linear

__all__ = ["ExtendedKalmanFilter"]

_LOG_2PI = math.log(2.0 * math.pi)
_S_NOT_SPD = (
    "measurements: innovation covariance S = H P H^T + R is not positive definite for "
    "sensor {!r} (check the sensor's R)"
)


def _joseph_update(
    x: FloatArray,
    P: FloatArray,
    H: FloatArray,
    nu: FloatArray,
    R: FloatArray,
    I: FloatArray,
    sid: str,
) -> tuple[FloatArray, FloatArray, float, float]:
    """One detection (Ramdaras eq. 16-22): ``(x, P, nis, log det S)``."""
    n = x.shape[0]
    PHT = P @ H.T
    S = H @ PHT + R
    dim_z = nu.shape[0]
    if dim_z == 1:  # scalar innovation: S^-1 is a division
        s11 = float(S[0, 0])
        if not s11 > 0.0:
            raise ValueError(_S_NOT_SPD.format(sid))
        K = PHT / s11
        nis = float(nu[0]) ** 2 / s11
        log_det_S = math.log(s11)
    else:
        try:
            L = np.linalg.cholesky(S)
        except np.linalg.LinAlgError:
            raise ValueError(_S_NOT_SPD.format(sid)) from None
        # One solve gives both S^-1 (H P) for the gain and S^-1 nu for the NIS.
        sol = np.linalg.solve(S, np.column_stack((PHT.T, nu)))
        K = sol[:, :n].T
        nis = float(nu @ sol[:, n])
        log_det_S = 2.0 * float(np.sum(np.log(np.diagonal(L))))
    x = x + K @ nu
    I_KH = I - K @ H
    P = I_KH @ P @ I_KH.T + K @ R @ K.T
    return x, 0.5 * (P + P.T), nis, log_det_S


def _check_t0(t0: float) -> float:
    t = float(t0)
    if not math.isfinite(t):
        raise ValueError(f"t0 must be finite, got {t0!r}")
    return t


class ExtendedKalmanFilter:
    """EKF over ``model`` (any :mod:`activetrack.models.motion` model).

    model: motion model (``activetrack.models.base.MotionModel``).
    x0: initial mean, shape ``(n,)``; P0: initial covariance ``(n, n)``, SPD.
    t0: time of ``x0`` in seconds.
    """

    def __init__(self, model: MotionModel, x0: ArrayLike, P0: ArrayLike, t0: float = 0.0):
        n = int(model.dim)
        x, P = check_prior(x0, P0, n)
        self._setup(model, x.copy(), P.copy(), _check_t0(t0), np.eye(n))

    @classmethod
    def many(
        cls, model: MotionModel, X0: ArrayLike, P0: ArrayLike, t0: float = 0.0
    ) -> list[ExtendedKalmanFilter]:
        """``k`` filters at once, from means ``X0`` ``(k, n)`` and covariances ``P0`` ``(k, n,
        n)``: the filters ``ExtendedKalmanFilter(model, X0[i], P0[i], t0)`` would be (the same
        checks, on the stack)."""
        n = int(model.dim)
        X = require_finite("x0", X0)
        if X.ndim != 2 or X.shape[1] != n:
            raise ValueError(f"x0 must have shape (k, {n}) for this model, got {X.shape}")
        P = require_spd("P0", P0)
        if P.shape != (X.shape[0], n, n):
            raise ValueError(f"P0 must have shape ({X.shape[0]}, {n}, {n}), got {P.shape}")
        t = _check_t0(t0)
        out = []
        for x, cov in zip(X, P, strict=True):
            f = cls.__new__(cls)
            f._setup(model, x.copy(), cov.copy(), t, np.eye(n))
            out.append(f)
        return out

    def _setup(
        self, model: MotionModel, x: FloatArray, P: FloatArray, t0: float, I: FloatArray
    ) -> None:
        self.model = model
        self._x = x
        self._P = P
        self._t = t0
        self._I = I
        # The pv-state models need no kinematics map (pv = x, d pv / dx = I).
        self._pv_state = bool(model.state_is_pv)
        self._linear_cache: tuple[float, FloatArray, FloatArray] | None = None
        self.last_info: UpdateInfo | None = None

    @property
    def time(self) -> float:
        """Time of the current estimate (s)."""
        return self._t

    @property
    def mean(self) -> np.ndarray:
        """Current state estimate, shape ``(n,)`` (a copy)."""
        return self._x.copy()

    @property
    def cov(self) -> np.ndarray:
        """Current error covariance, shape ``(n, n)`` (a copy)."""
        return self._P.copy()

    @staticmethod
    def means_many(filters: Sequence[ExtendedKalmanFilter]) -> FloatArray:
        """The :attr:`mean` of many filters stacked, ``(k, n)`` (a copy)."""
        return np.array([f._x for f in filters], dtype=float)

    @staticmethod
    def covs_many(filters: Sequence[ExtendedKalmanFilter]) -> FloatArray:
        """The :attr:`cov` of many filters stacked, ``(k, n, n)`` (a copy)."""
        return np.array([f._P for f in filters], dtype=float)

    def predict(self, t: float) -> None:
        """Propagate the estimate to time ``t`` (>= ``time``); Valverde eq. 2-4."""
        t = check_predict_time(t, self._t)
        dt = t - self._t
        if dt > 0.0:
            model, x = self.model, self._x
            if model.is_linear:
                # Constant F and Q for a given dt: reuse them across steps of the same length.
                cache = self._linear_cache
                if cache is None or cache[0] != dt:
                    F = as_linear(model).transition_matrix(dt)
                    cache = (dt, F, model.process_noise(dt))
                    self._linear_cache = cache
                _, F, Q = cache
                x_new = None  # F x
            else:
                F = model.jacobian(x, dt)
                Q = model.process_noise(dt, x)
                x_new = np.asarray(model.propagate(x, dt), dtype=float)
            kernels = ekf_kernels()
            if kernels is not None:  # the same algebra in one compiled call
                Fx, self._P = kernels.predict(x, self._P, F, Q)
            else:
                Fx = F @ x if x_new is None else x_new
                P = F @ self._P @ F.T + Q
                self._P = 0.5 * (P + P.T)
            self._x = Fx if x_new is None else x_new
        self._t = t

    @classmethod
    def predict_many(cls, filters: Sequence[ExtendedKalmanFilter], t: float) -> None:
        """:meth:`predict` of many filters to ``t``: those of one linear model and one time
        step stacked (numpy runs each stacked product as that filter's own: the same numbers
        to the bit, tested), the others (nonlinear models; the compiled kernels' mode) one by
        one."""
        if ekf_kernels() is not None:
            for f in filters:
                f.predict(t)
            return
        groups: dict[tuple[int, float], list[ExtendedKalmanFilter]] = {}
        for f in filters:
            t_f = check_predict_time(t, f._t)
            dt = t_f - f._t
            if dt > 0.0 and f.model.is_linear:
                groups.setdefault((id(f.model), dt), []).append(f)
            else:
                f.predict(t)
        for (_, dt), group in groups.items():
            model = group[0].model
            F = as_linear(model).transition_matrix(dt)
            Q = model.process_noise(dt)
            X = np.array([f._x for f in group])
            P = np.array([f._P for f in group])
            Fx = (F @ X[:, :, None])[:, :, 0]
            P = F @ P @ F.T + Q
            P = 0.5 * (P + np.swapaxes(P, 1, 2))
            for k, f in enumerate(group):
                f._x, f._P, f._t = Fx[k], P[k], float(t)  # dt > 0: t is after f's time
                f._linear_cache = (dt, F, Q)

    def update(self, measurements: Sequence[Measurement]) -> UpdateInfo:
        """Fuse the measurements taken at the current time, one after another.

        Returns an :class:`UpdateInfo` with the summed NIS ``nu^T S^-1 nu`` and the Gaussian
        log-likelihood of the detections. Non-detections are counted and skipped.
        """
        check_measurement_times(measurements, self._t)
        model, x, P, I = self.model, self._x, self._P, self._I
        kernels = ekf_kernels()
        nis_each: list[float] = []
        nis_total = 0.0
        log_lik = 0.0
        dof = 0
        n_missed = 0
        for m in measurements:
            if m.z is None:
                n_missed += 1
                nis_each.append(math.nan)
                continue
            sensor, s = m.sensor, m.sensor_state
            if self._pv_state:
                _, H, nu = sensor.linearize(x, s, m.z)
            else:  # chain rule to the model state (contract state_jacobian)
                _, H_pv, nu = sensor.linearize(model.kinematics(x), s, m.z)
                H = np.asarray(H_pv @ model.kinematics_jacobian(x), dtype=float)
            R = sensor.R
            if kernels is not None:  # the same algebra in one compiled call
                x, P, nis, log_det_S, ok = kernels.update(x, P, H, nu, np.asarray(R, dtype=float))
                if not ok:
                    raise ValueError(_S_NOT_SPD.format(m.sensor_id))
            else:
                x, P, nis, log_det_S = _joseph_update(x, P, H, nu, R, I, m.sensor_id)
            dim_z = nu.shape[0]
            nis_each.append(nis)
            nis_total += nis
            dof += dim_z
            log_lik -= 0.5 * (nis + log_det_S + dim_z * _LOG_2PI)
        self._x, self._P = x, P
        n_det = len(nis_each) - n_missed
        info = UpdateInfo(
            time=self._t,
            n_detections=n_det,
            n_missed=n_missed,
            nis=nis_total if n_det else math.nan,
            dof=dof,
            nis_per_measurement=tuple(nis_each),
            log_likelihood=log_lik,
            sensor_ids=tuple(m.sensor_id for m in measurements),
        )
        self.last_info = info
        return info

    def update_pda(
        self,
        measurements: Sequence[Measurement],
        beta: ArrayLike,
        *,
        linearization: tuple[FloatArray, FloatArray] | None = None,
    ) -> UpdateInfo:
        """The PDAF update (Bar-Shalom, Daum & Huang 2009 eq. 23-27) with one scan's detections
        (one sensor and platform state) and their association probabilities ``beta`` ``(m +
        1,)`` (``beta[0]``: none is the target's; 1 leaves the prediction). ``linearization``:
        ``(H, nu)``, the Jacobian ``(d, n)`` at the current mean and the detections' wrapped
        residuals ``(m, d)`` where the caller has them (the tracker, once per scan: the same
        numbers :func:`~activetrack.filters.jpda.pda_residuals` gives); computed here
        otherwise."""
        check_measurement_times(measurements, self._t)
        b = pda_weights(measurements, beta)
        if b[0] < 1.0:
            sensor, s = measurements[0].sensor, measurements[0].sensor_state
            if linearization is None:
                Z = np.stack([np.asarray(m.z, dtype=float) for m in measurements])
                H, nu = pda_residuals(self._x, self._P, Z, sensor, s, self.model)
            else:
                H, nu = linearization
            self._x, self._P = pda_update(self._x, self._P, H, sensor.R, nu, b)
        info = UpdateInfo(
            time=self._t,
            n_detections=len(measurements),
            sensor_ids=tuple(m.sensor_id for m in measurements),
        )
        self.last_info = info
        return info

    @classmethod
    def update_pda_many(
        cls,
        filters: Sequence[ExtendedKalmanFilter],
        H: FloatArray,
        nu: FloatArray,
        beta: FloatArray,
        R: ArrayLike,
        sensor_id: str = "",
    ) -> None:
        """:meth:`update_pda` of ``G`` filters at once, each with ``m`` detections of one scan
        and its ``linearization``: Jacobians ``H`` ``(G, d, n)`` at the current means, wrapped
        residuals ``nu`` ``(G, m, d)``, probabilities ``beta`` ``(G, m + 1)`` and the sensor's
        ``R`` ``(d, d)``. The filters must be at the scan's time (the tracker predicted them).
        The same algebra stacked (:func:`activetrack.filters.jpda.pda_update_many`)."""
        B = np.asarray(beta, dtype=float)
        G = len(filters)
        m = B.shape[1] - 1 if B.ndim == 2 else -1
        if B.shape != (G, m + 1) or np.shape(nu) != (G, m, np.shape(H)[1]):
            raise ValueError(
                f"beta (G, m + 1) and nu (G, m, d) expected for {G} filters, got "
                f"{B.shape}, {np.shape(nu)}"
            )
        B = pda_probabilities(B, (G, m + 1))
        go = np.flatnonzero(B[:, 0] < 1.0).tolist()
        if go:
            X = np.array([filters[g]._x for g in go])
            P = np.array([filters[g]._P for g in go])
            R = np.asarray(R, dtype=float)
            X, P = pda_update_many(X, P, np.asarray(H)[go], R, np.asarray(nu)[go], B[go])
            for k, g in enumerate(go):
                filters[g]._x, filters[g]._P = X[k], P[k]
        ids = (sensor_id,) * m
        for f in filters:
            f.last_info = UpdateInfo(time=f._t, n_detections=m, sensor_ids=ids)

    def step(self, t: float, measurements: Sequence[Measurement]) -> UpdateInfo:
        """``predict(t)`` then ``update(measurements)``."""
        self.predict(t)
        return self.update(measurements)
