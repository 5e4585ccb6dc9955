"""Beta-cautious greedy localisation with an infinite-line (ambiguous bearing) sensor (Vander
Hook, Tokekar, Isler (003), sec. II-III, Algorithm 1).

The target is stationary, its estimate N(x_hat, P) in 2-D. The sensor measures the bearing
modulo pi; the EKF takes the more likely of z and z + pi, wrong when the target lies behind
the sensor (eq. 2). Measuring from far enough away keeps that probability below beta (eq. 3);
measuring perpendicular to the major axis of P reduces its larger eigenvalue (Lemma 2), from
the closer of the two candidate points (line 7). Positions ``(..., 2)``, covariances ``(...,
2, 2)``, all batched.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from statistics import NormalDist

import numpy as np

from activetrack.angles import wrap_angle, wrap_half_angle
from activetrack.arraytypes import ArrayLike
from activetrack.checks import (
    require_finite,
    require_in_range,
    require_nonnegative,
    require_positive,
    require_spd,
    symmetrize,
)
from activetrack.data import Command, PlatformSnapshot, TrackEstimate

__all__ = [
    "TAILS",
    "AmbiguousUpdate",
    "CautiousAction",
    "CautiousController",
    "CautiousPlanner",
    "ambiguous_bearing_update",
    "caution_gamma",
    "cautious_range",
    "measurement_waypoint",
    "position_estimate",
    "principal_axes",
    "reduction_reached",
    "sigma_beta",
]


TAILS = ("two_sided", "one_sided")


def sigma_beta(beta: float, tail: str = "two_sided") -> float:
    """Largest beta-cautious innovation standard deviation (line after eq. 3), radians.

    ``tail="two_sided"`` (as printed): pi / (2 Phi^-1(1 - beta / 2)), the probability beta that
    a zero-mean Gaussian innovation exceeds |pi/2| (target behind the sensor, eq. 2), beta in
    (0, 1); Algorithm 1 line 1 prints sigma_beta^2, the text and the tail argument give
    sigma_beta. ``"one_sided"``: pi / (2 Phi^-1(1 - beta)), beta in (0, 0.5] (inf at 0.5), the
    variant that reproduces Table I (docs/vanderhook.md).
    """
    if tail == "two_sided":
        beta = require_in_range("beta", beta, 0.0, 1.0, lo_inclusive=False, hi_inclusive=False)
        return math.pi / (2.0 * NormalDist().inv_cdf(1.0 - 0.5 * beta))
    if tail == "one_sided":
        beta = require_in_range("beta", beta, 0.0, 0.5, lo_inclusive=False)
        if beta == 0.5:
            return math.inf
        return math.pi / (2.0 * NormalDist().inv_cdf(1.0 - beta))
    raise ValueError(f"tail must be one of {TAILS}, got {tail!r}")


def caution_gamma(beta: float, sigma_s: float, tail: str = "two_sided") -> float:
    """gamma = sigma_beta^2 / sigma_s^2 (Lemma 4), one cautious step's variance reduction (inf
    for one-sided beta = 0.5). ValueError unless gamma > 1 (else the sensor is too noisy to be
    beta-cautious at any range)."""
    sigma_s = require_positive("sigma_s", sigma_s)
    sb = sigma_beta(beta, tail)
    if not sb > sigma_s:
        raise ValueError(
            f"sigma_s must be < sigma_beta(beta={beta}) = {sb:.6g} rad for a cautious "
            f"strategy to exist (003 sec. III), got {sigma_s:.6g}"
        )
    return (sb / sigma_s) ** 2


def principal_axes(P: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """``(variances (..., 2), major (..., 2))`` of ``P (..., 2, 2)``: sigma^2(1) >= sigma^2(2)
    and the unit eigenvector of sigma^2(1) (003 sec. II notation)."""
    w, V = np.linalg.eigh(symmetrize(P))
    return w[..., ::-1], V[..., :, 1]


def cautious_range(
    P: ArrayLike, alpha: ArrayLike, beta: float, sigma_s: float, tail: str = "two_sided"
) -> np.ndarray:
    """Smallest beta-cautious range (eq. 3), ``(...)``.

    r >= sqrt((sigma^2(1) sin^2 alpha + sigma^2(2) cos^2 alpha) / (sigma_beta^2 - sigma_s^2)),
    alpha the angle between the sensor direction (seen from x_hat) and the major axis.
    alpha = pi/2 gives Algorithm 1 line 6, r = sqrt(sigma^2(1) / (sigma_beta^2 - sigma_s^2)).
    P ``(..., 2, 2)`` SPD; alpha ``(...)``; 0 when sigma_beta is infinite.
    """
    P = require_spd("P", P)
    alpha = require_finite("alpha", alpha)
    gamma = caution_gamma(beta, sigma_s, tail)
    var, _ = principal_axes(P)
    s, c = np.sin(alpha), np.cos(alpha)
    across = var[..., 0] * s * s + var[..., 1] * c * c
    return np.sqrt(across / (float(sigma_s) ** 2 * (gamma - 1.0)))


def measurement_waypoint(
    x_hat: ArrayLike, P: ArrayLike, robot: ArrayLike, r: ArrayLike, tie_rtol: float = 1e-9
) -> np.ndarray:
    """Next sensing location s_i (Algorithm 1, lines 5-7), ``(..., 2)``.

    Of the two points at range r from x_hat perpendicular to the major axis, the one closer to
    the robot. For a circular P (eigenvalues equal to ``tie_rtol``) the axis perpendicular to
    the robot's direction: the waypoint on the segment toward the robot, the closest of all.

    x_hat, robot: ``(..., 2)``; P: ``(..., 2, 2)``; r: ``(...)`` >= 0.
    """
    x_hat = require_finite("x_hat", x_hat)
    robot = require_finite("robot", robot)
    r = require_finite("r", r)
    if np.any(r < 0.0):
        raise ValueError("r must be >= 0")
    var, major = principal_axes(require_spd("P", P))
    minor = np.stack([-major[..., 1], major[..., 0]], axis=-1)
    to_robot = robot - x_hat
    dist = np.linalg.norm(to_robot, axis=-1, keepdims=True)
    circular = (var[..., 0] - var[..., 1] <= tie_rtol * var[..., 0])[..., None] & (dist > 0.0)
    toward = to_robot / np.where(dist > 0.0, dist, 1.0)
    side = np.where(np.sum(minor * to_robot, axis=-1, keepdims=True) >= 0.0, 1.0, -1.0)
    direction = np.where(circular, toward, side * minor)
    return x_hat + np.asarray(r)[..., None] * direction


@dataclass(frozen=True)
class AmbiguousUpdate:
    """Result of :func:`ambiguous_bearing_update`: innovation y in [-pi/2, pi/2), its variance
    S and the chosen full bearing in [-pi, pi), batched like the inputs."""

    mean: np.ndarray
    cov: np.ndarray
    innovation: np.ndarray
    S: np.ndarray
    bearing: np.ndarray


def ambiguous_bearing_update(
    x_hat: ArrayLike, P: ArrayLike, z: ArrayLike, sensor: ArrayLike, sigma_s: float
) -> AmbiguousUpdate:
    """EKF update of a stationary 2-D target with an ambiguous bearing (003 sec. II-III).

    h(x, s) = atan2(x_y - s_y, x_x - s_x), H = [-dy, dx] / r^2, S = H P H^T + sigma_s^2,
    K = P H^T / S, P in Joseph form. The line measurement z stands for the bearings z and
    z + pi, whose innovations share S, so the more likely one has the smaller |y|:
    y = wrap_half_angle(z - h) (sec. III, ``AmbiguousBearingSensor.residual``).

    x_hat, sensor: ``(..., 2)``; P ``(..., 2, 2)`` SPD; z ``(...)`` radians (any branch);
    sigma_s > 0 rad. Raises ValueError when the sensor sits on x_hat (range 0).
    """
    x_hat = require_finite("x_hat", x_hat)
    sensor = require_finite("sensor", sensor)
    P = require_spd("P", P)
    z = require_finite("z", z)
    sigma_s = require_positive("sigma_s", sigma_s)
    d = x_hat - sensor
    r2 = np.sum(d * d, axis=-1)
    if np.any(r2 == 0.0):
        raise ValueError("sensor coincides with x_hat (range 0): the range must be > 0")
    zhat = np.arctan2(d[..., 1], d[..., 0])
    H = np.stack([-d[..., 1], d[..., 0]], axis=-1) / r2[..., None]  # (..., 2)
    y = wrap_half_angle(z - zhat)
    PHt = np.einsum("...ij,...j->...i", P, H)
    S = np.sum(H * PHt, axis=-1) + sigma_s**2
    K = PHt / S[..., None]
    mean = x_hat + K * y[..., None]
    IKH = np.eye(2) - K[..., :, None] * H[..., None, :]
    cov = IKH @ P @ np.swapaxes(IKH, -1, -2) + sigma_s**2 * K[..., :, None] * K[..., None, :]
    return AmbiguousUpdate(
        mean=mean, cov=symmetrize(cov), innovation=y, S=S, bearing=wrap_angle(zhat + y)
    )


def reduction_reached(P: ArrayLike, P0: ArrayLike, c_d: float) -> np.ndarray:
    """Stopping rule of Algorithm 1 (line 4 negated), bool ``(...)``: sigma(1) < c_d sigma_0(1)
    and sigma(2) < c_d sigma_0(2) along the principal axes, largest first."""
    c_d = require_in_range("c_d", c_d, 0.0, 1.0, lo_inclusive=False, hi_inclusive=False)
    var, _ = principal_axes(P)
    var0, _ = principal_axes(P0)
    return np.all(var < c_d**2 * var0, axis=-1)


def position_estimate(mean: ArrayLike, cov: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """``(mean (2,), cov (2, 2))`` of an estimate given as position (2,) or pv (4,)."""
    mean = require_finite("mean", mean)
    cov = require_finite("cov", cov)
    if mean.shape == (2,) and cov.shape == (2, 2):
        return mean, cov
    if mean.shape == (4,) and cov.shape == (4, 4):
        idx = np.array([0, 2])
        return mean[idx], cov[np.ix_(idx, idx)]
    raise ValueError(
        f"mean/cov must be position (2,)/(2, 2) or pv (4,)/(4, 4), got {mean.shape}/{cov.shape}"
    )


@dataclass(frozen=True)
class CautiousAction:
    """Drive to ``waypoint`` (2,) and measure for ``dwell`` s, or stop (``done``, waypoint
    None); ``range`` to x_hat and straight-line ``travel`` from the robot in m."""

    done: bool
    waypoint: np.ndarray | None
    range: float
    travel: float
    dwell: float


@dataclass(frozen=True)
class CautiousPlanner:
    """Algorithm 1 as a stateless step, one call per processed measurement.

    sigma_s: sensor noise (rad); beta: caution risk in (0, 1); c_d: desired reduction of both
    standard deviations in (0, 1); prior_cov: Sigma_0 (2, 2) or pv (4, 4), the reference of
    the stopping rule; t_m: dwell per measurement (s); r_min: smallest standoff (m, > 0 when
    sigma_beta is infinite); max_measurements: hard stop (None: none); tail: see
    :func:`sigma_beta`.
    """

    sigma_s: float
    prior_cov: np.ndarray
    beta: float = 0.1
    c_d: float = 0.1
    t_m: float = 60.0
    r_min: float = 0.0
    max_measurements: int | None = None
    tail: str = "two_sided"
    _P0: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        gamma = caution_gamma(self.beta, self.sigma_s, self.tail)
        require_in_range("c_d", self.c_d, 0.0, 1.0, lo_inclusive=False, hi_inclusive=False)
        require_nonnegative("t_m", self.t_m)
        require_nonnegative("r_min", self.r_min)
        if math.isinf(gamma) and self.r_min <= 0.0:
            raise ValueError("r_min must be > 0 when sigma_beta is infinite (no caution range)")
        if self.max_measurements is not None and self.max_measurements < 1:
            raise ValueError(f"max_measurements must be >= 1 or None, got {self.max_measurements}")
        P0 = np.asarray(self.prior_cov, dtype=float)
        if P0.shape == (4, 4):
            P0 = P0[np.ix_([0, 2], [0, 2])]
        if P0.shape != (2, 2):
            raise ValueError(f"prior_cov must be (2, 2) or pv (4, 4), got {P0.shape}")
        object.__setattr__(self, "_P0", require_spd("prior_cov", P0))

    @property
    def gamma(self) -> float:
        return caution_gamma(self.beta, self.sigma_s, self.tail)

    def is_done(self, cov: ArrayLike, n_measurements: int = 0) -> bool:
        """Stopping rule (Algorithm 1 line 4, and ``max_measurements``)."""
        if self.max_measurements is not None and n_measurements >= self.max_measurements:
            return True
        P = require_finite("cov", cov)
        if P.shape == (4, 4):
            P = P[np.ix_([0, 2], [0, 2])]
        if P.shape != (2, 2):
            raise ValueError(f"cov must be (2, 2) or pv (4, 4), got {P.shape}")
        return bool(reduction_reached(P, self._P0, self.c_d))

    def next_action(
        self, mean: ArrayLike, cov: ArrayLike, robot_position: ArrayLike, n_measurements: int = 0
    ) -> CautiousAction:
        """Algorithm 1 lines 4-7 for the target estimate ``mean``/``cov`` (position (2,)/(2, 2)
        or pv (4,)/(4, 4)), the robot at ``robot_position`` ((2,) or pv (4,)) and the
        ``n_measurements`` taken so far."""
        x_hat, P = position_estimate(mean, cov)
        robot = require_finite("robot_position", robot_position)
        if robot.shape == (4,):
            robot = robot[[0, 2]]
        if robot.shape != (2,):
            raise ValueError(f"robot_position must be (2,) or pv (4,), got {robot.shape}")
        if self.is_done(P, n_measurements):
            return CautiousAction(True, None, 0.0, 0.0, 0.0)
        r_cautious = cautious_range(P, 0.5 * math.pi, self.beta, self.sigma_s, self.tail)
        r = max(float(r_cautious), self.r_min)
        waypoint = measurement_waypoint(x_hat, P, robot, r)
        travel = float(np.linalg.norm(waypoint - robot))
        return CautiousAction(False, waypoint, r, travel, float(self.t_m))

    def update(
        self, mean: ArrayLike, cov: ArrayLike, z: ArrayLike, sensor_position: ArrayLike
    ) -> AmbiguousUpdate:
        """EKF update of the position estimate with an ambiguous bearing z measured at
        sensor_position ((2,) or pv (4,)); see :func:`ambiguous_bearing_update`."""
        x_hat, P = position_estimate(mean, cov)
        s = require_finite("sensor_position", sensor_position)
        if s.shape == (4,):
            s = s[[0, 2]]
        return ambiguous_bearing_update(x_hat, P, z, s, self.sigma_s)


_ARRIVED = 1e-6  # m: a robot this close to its waypoint is on it


class CautiousController:
    """Per-epoch commands for the one robot ``robot_id`` (top speed ``v_max``, decisions
    ``dt`` apart) from the beta-cautious ``planner``; no randomness."""

    def __init__(self, robot_id: str, v_max: float, dt: float, planner: CautiousPlanner):
        self.robot_id = robot_id
        self.dt = dt
        self.v_max = v_max
        self.dwell_epochs = max(1, math.ceil(float(planner.t_m) / dt))
        self.planner = planner
        self.waypoint: np.ndarray | None = None
        self.dwell_left = 0
        self.measurements = 0
        self.awaiting = False  # a measurement was requested for the next epoch
        self.done = False

    def decide(self, epoch: int, track: TrackEstimate, robot: PlatformSnapshot) -> Command:
        position = robot.pv[[0, 2]]
        if self.awaiting:  # the track now holds the measurement taken at this epoch
            self.awaiting = False
            self.measurements += 1
            self.waypoint = None
        if self.waypoint is None and not self.done:
            action = self.planner.next_action(
                track.state, track.state_cov, position, self.measurements
            )
            self.done = action.done
            self.waypoint = None if action.done else np.asarray(action.waypoint, dtype=float)
            self.dwell_left = self.dwell_epochs
        if self.done:
            return self._command(epoch, robot, robot.heading, 0.0, take=False)
        offset = self.waypoint - position
        distance = float(np.hypot(*offset))
        if distance > _ARRIVED:  # drive straight at the waypoint, arriving exactly on it
            heading = math.atan2(offset[1], offset[0])
            return self._command(
                epoch, robot, heading, min(self.v_max, distance / self.dt), take=False
            )
        self.dwell_left -= 1  # stopped on the waypoint; the last dwell epoch ends in a measurement
        take = self.dwell_left <= 0
        self.awaiting = take
        return self._command(epoch, robot, robot.heading, 0.0, take=take)

    def _command(
        self, epoch: int, robot: PlatformSnapshot, heading: float, speed: float, take: bool
    ) -> Command:
        w = self.waypoint
        return Command(
            self.robot_id,
            epoch,
            float(wrap_angle(heading - robot.heading)),
            speed - robot.speed,
            heading,
            speed,
            take_measurement=take,
            waypoint=None if w is None else (float(w[0]), float(w[1])),
        )
