"""Batched Monte Carlo of the beta-cautious strategy and a greedy baseline (003 sec. V-A).

Table I's setup: prior N((0, 0), sigma_0^2 I), true targets drawn from it, the robot starts at
(r0_hat, 0), moves at 1 m/s and dwells t_m per measurement. All runs of a batch advance
together, one measurement per iteration; a run stops (masked) when Algorithm 1's rule is met.
Both strategies measure perpendicular to the major axis from the closer side (Lemma 2,
Algorithm 1 line 7), at the beta-cautious range of eq. 3 floored at r_min (``"cautious"``) or a
fixed standoff ``greedy_range`` (``"greedy"``: faster, but often with the target behind).

A *wrong-side* measurement has the true bearing more than pi/2 from the predicted one, so the
EKF's "more likely" bearing (eq. 2) is the wrong one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from activetrack.angles import wrap_angle
from activetrack.checks import require_positive
from activetrack.planning.cautious import (
    ambiguous_bearing_update,
    cautious_range,
    measurement_waypoint,
    reduction_reached,
)

__all__ = ["SIGMA_S_DEFAULT", "LocalisationBatch", "simulate_localisation"]

# 15 degrees, the empirical sensor noise of the paper (sec. V).
SIGMA_S_DEFAULT = float(np.deg2rad(15.0))


@dataclass(frozen=True)
class LocalisationBatch:
    """Per-run results, arrays of shape (M,)."""

    n_measurements: np.ndarray  # measurements taken
    distance: np.ndarray  # metres travelled (= seconds at 1 m/s)
    first_leg: np.ndarray  # d(s0, s1), metres
    r0_true: np.ndarray  # range from the start to the true target, metres
    final_error: np.ndarray  # ||x_hat - x*|| at the end, metres
    wrong_side_events: np.ndarray  # number of wrong-side measurements
    converged: np.ndarray  # bool: the stopping rule was met (not the measurement cap)
    final_wrong_side: np.ndarray  # bool: x* and the final x_hat on opposite sides of s_N
    t_m: float

    @property
    def time(self) -> np.ndarray:
        """Execution time N t_m + D (s, robot at 1 m/s)."""
        return self.n_measurements * self.t_m + self.distance

    @property
    def wrong_side(self) -> np.ndarray:
        """bool (M,): at least one wrong-side measurement in the run."""
        return self.wrong_side_events > 0


@dataclass
class _Runs:
    """A batch of localisations in progress (arrays over runs, updated in place)."""

    x_true: np.ndarray  # (M, 2)
    r0_true: np.ndarray  # range from the start to the true target
    robot: np.ndarray  # (M, 2)
    x_hat: np.ndarray  # (M, 2)
    P: np.ndarray  # (M, 2, 2)
    n: np.ndarray  # measurements taken
    distance: np.ndarray
    first_leg: np.ndarray
    wrong: np.ndarray  # wrong-side measurements
    active: np.ndarray  # bool: still measuring

    @classmethod
    def start(cls, x_true: np.ndarray, r0_hat: float, P0: np.ndarray) -> _Runs:
        M = len(x_true)
        robot = np.tile([float(r0_hat), 0.0], (M, 1))
        return cls(
            x_true=x_true,
            r0_true=np.linalg.norm(x_true - robot, axis=-1),
            robot=robot,
            x_hat=np.zeros((M, 2)),
            P=np.tile(P0, (M, 1, 1)),
            n=np.zeros(M, dtype=int),
            distance=np.zeros(M),
            first_leg=np.zeros(M),
            wrong=np.zeros(M, dtype=int),
            active=np.ones(M, dtype=bool),
        )

    def measure(self, r: np.ndarray, sigma_s: float, rng) -> None:
        """The active runs drive to their next sensing location at range ``r`` (M,) from
        x_hat, take one ambiguous bearing and update the estimate (Algorithm 1, lines 5-8)."""
        active = self.active
        waypoint = measurement_waypoint(self.x_hat, self.P, self.robot, r)
        leg = np.linalg.norm(waypoint - self.robot, axis=-1)
        self.first_leg = np.where(active & (self.n == 0), leg, self.first_leg)
        self.distance += np.where(active, leg, 0.0)
        self.robot = np.where(active[:, None], waypoint, self.robot)
        d_true = self.x_true - self.robot
        true_bearing = np.arctan2(d_true[:, 1], d_true[:, 0])
        d_hat = self.x_hat - self.robot
        predicted = np.arctan2(d_hat[:, 1], d_hat[:, 0])
        self.wrong += active & (np.abs(wrap_angle(true_bearing - predicted)) > 0.5 * np.pi)
        # Infinite-line sensor: bearing + noise, known only modulo pi (sec. II).
        z = true_bearing + sigma_s * rng.standard_normal(len(active))
        upd = ambiguous_bearing_update(self.x_hat, self.P, z, self.robot, sigma_s)
        self.x_hat = np.where(active[:, None], upd.mean, self.x_hat)
        self.P = np.where(active[:, None, None], upd.cov, self.P)
        self.n += active

    def result(self, P0: np.ndarray, c_d: float, t_m: float) -> LocalisationBatch:
        # Ending on the wrong side: seen from the last sensing location, the final estimate and
        # the true target are more than pi/2 apart (the last line was resolved the wrong way).
        d_true, d_hat = self.x_true - self.robot, self.x_hat - self.robot
        return LocalisationBatch(
            n_measurements=self.n,
            distance=self.distance,
            first_leg=self.first_leg,
            r0_true=self.r0_true,
            final_error=np.linalg.norm(self.x_hat - self.x_true, axis=-1),
            wrong_side_events=self.wrong,
            converged=reduction_reached(self.P, P0, c_d),
            final_wrong_side=np.sum(d_true * d_hat, axis=-1) < 0.0,
            t_m=float(t_m),
        )


def simulate_localisation(
    n_runs,
    rng,
    *,
    sigma0=60.0,
    r0_hat=100.0,
    beta=0.1,
    c_d=0.1,
    t_m=60.0,
    sigma_s=SIGMA_S_DEFAULT,
    strategy="cautious",
    greedy_range=10.0,
    r_min=1.0,
    max_measurements=60,
    x_true=None,
    tail="two_sided",
):
    """Run ``n_runs`` localisations at once; returns a :class:`LocalisationBatch`.

    x_true: optional true target positions (M, 2); default drawn from the prior with ``rng``.
    tail: the sigma_beta formula (``activetrack.planning.cautious.sigma_beta``).
    """
    if int(n_runs) < 1:
        raise ValueError(f"n_runs must be >= 1, got {n_runs}")
    if strategy not in ("cautious", "greedy"):
        raise ValueError(f"strategy must be 'cautious' or 'greedy', got {strategy!r}")
    sigma0 = require_positive("sigma0", sigma0)
    greedy_range = require_positive("greedy_range", greedy_range)
    M = int(n_runs)
    P0 = sigma0**2 * np.eye(2)
    if x_true is None:
        x_true = sigma0 * rng.standard_normal((M, 2))
    runs = _Runs.start(np.asarray(x_true, dtype=float), r0_hat, P0)
    for _ in range(max_measurements):
        runs.active &= ~reduction_reached(runs.P, P0, c_d)
        if not runs.active.any():
            break
        if strategy == "cautious":
            r = np.maximum(cautious_range(runs.P, 0.5 * np.pi, beta, sigma_s, tail), r_min)
        else:
            r = np.full(M, greedy_range)
        runs.measure(r, sigma_s, rng)
    return runs.result(P0, c_d, t_m)
