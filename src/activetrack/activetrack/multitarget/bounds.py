"""Per-target PCRLB of a multi-target run, with measurement-origin uncertainty (the IRF).

For each target n, from its birth epoch b (Hernandez 2004 eq. 3-4, 8-9; the clutter through
the information reduction factor of Niu, Willett & Bar-Shalom 2001 as in Hernandez, Farina &
Ristic 2006, the "IRF approach")::

    J_b     = C_0^{-1} + J_Z(b)                                (J_Z(0) = 0: no scan at epoch 0)
    J_{k+1} = (Q + F J_k^{-1} F^T)^{-1} + J_Z(k+1),   b <= k < last alive epoch,
    J_Z(k)  = sum_s observed[k-1, s, n] * E[ q_s H_s^T R_s^{-1} H_s ],

with ``C_0`` the target's prior (the distribution of its state at birth: the simulator draws
it there), F and Q its NCV dynamics, and ``q_s`` the IRF of sensor s for its ``pd``, clutter
density and the tracker's gate (:class:`activetrack.models.clutter.ClutteredSensor`; ``q_s``
replaces the ``pd`` factor of eq. 8). The expectation is over Monte Carlo samples of the target
(Hernandez sec. 3.2): its prior at birth propagated through its noisy dynamics, one generator
stream for all targets in scenario order. ``record.observed`` says which sensor had the target
in its field of view or beam; the bound's sensors therefore carry no field of view of their
own (the fixed sector is not applied twice), only the IRF scaling and the detection ranges.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from activetrack.arraytypes import FloatArray
from activetrack.bounds.pcrlb import (
    covariance_bound,
    gaussian_samples,
    measurement_information,
    pcrlb_step,
    propagate_samples,
)
from activetrack.models.base import as_linear
from activetrack.models.clutter import ClutteredSensor
from activetrack.multitarget.data import MultiRunRecord
from activetrack.scenarios.build import build_motion_model, build_scan_sensors
from activetrack.scenarios.schema import Scenario, TargetConfig

__all__ = ["BOUND_SAMPLES", "alive_mask", "bound_sensors", "target_bounds"]

# Monte Carlo samples of each target's prior (Hernandez used 1,000; closed_loop.batch too).
BOUND_SAMPLES = 1000


def _targets(scenario: Scenario) -> list[TargetConfig]:
    if scenario.targets is None:
        raise ValueError("scenario.targets: a multi-target scenario (a targets: list) is needed")
    return list(scenario.targets)


def _check_shapes(scenario: Scenario, record: MultiRunRecord) -> int:
    """K (epochs 1..K) of a record whose arrays fit the scenario; ValueError otherwise."""
    targets = _targets(scenario)
    truth = np.asarray(record.truth)
    N, P = len(targets), len(scenario.platforms)
    if truth.ndim != 3 or truth.shape[0] < 2 or truth.shape[1:] != (N, 4):
        raise ValueError(
            f"record.truth must be (K+1, {N}, 4) with K >= 1 (pv of the scenario's {N} "
            f"targets at epochs 0..K), got {truth.shape}"
        )
    K = truth.shape[0] - 1
    if tuple(record.target_ids) != tuple(t.id for t in targets):
        raise ValueError(
            f"record.target_ids must be the scenario's targets in order "
            f"{[t.id for t in targets]}, got {list(record.target_ids)}"
        )
    if len(record.tracks) != K + 1:
        raise ValueError(
            f"record.tracks must hold one TrackSet per epoch 0..K ({K + 1}), "
            f"got {len(record.tracks)}"
        )
    paths = np.asarray(record.platform_paths)
    if paths.shape != (K + 1, P, 4) or not np.isfinite(paths).all():
        raise ValueError(
            f"record.platform_paths must be finite (K+1, P, 4) = ({K + 1}, {P}, 4), "
            f"got shape {paths.shape}"
        )
    return K


def alive_mask(scenario: Scenario, record: MultiRunRecord) -> np.ndarray:
    """``(K+1, N)`` bool: target n alive at epoch k (its truth row is not NaN).

    Checks the record against the scenario (shapes, target order) and that each target is
    alive exactly for epochs ``birth <= k < death``, as the scenario says; ValueError naming
    the field otherwise."""
    K = _check_shapes(scenario, record)
    truth = np.asarray(record.truth, dtype=float)
    alive = ~np.isnan(truth[..., 0])
    if not np.isfinite(truth[alive]).all():
        raise ValueError("record.truth: an alive target's row must be finite (all 4 entries)")
    k = np.arange(K + 1)
    for n, t in enumerate(_targets(scenario)):
        death = math.inf if t.death is None else t.death
        expected = (k >= t.birth) & (k < death)
        if not np.array_equal(alive[:, n], expected):
            raise ValueError(
                f"record.truth: target {t.id!r} must be alive (not NaN) exactly at epochs "
                f"birth <= k < death ({t.birth}, {t.death}), got alive at "
                f"{np.flatnonzero(alive[:, n]).tolist()}"
            )
    return alive


def bound_sensors(scenario: Scenario) -> tuple[list[ClutteredSensor], list[int]]:
    """Each sensor in scenario order (platforms, then their sensors) as the bound sees it: the
    IRF scaling of its clutter, ``pd`` and the tracker's gate, no field of view or beam; and
    the index of its platform."""
    platform_ids = [p.id for p in scenario.platforms]
    sensors: list[ClutteredSensor] = []
    columns: list[int] = []
    for pid, model in build_scan_sensors(scenario).values():
        sensors.append(replace(model, fov_width=None, beam_width=None))
        columns.append(platform_ids.index(pid))
    return sensors, columns


def _check_observed(scenario: Scenario, record: MultiRunRecord, K: int, S: int) -> np.ndarray:
    ids = [s.id for p in scenario.platforms for s in p.sensors]
    if tuple(record.sensor_ids) != tuple(ids):
        raise ValueError(
            f"record.sensor_ids must be the scenario's sensors in order {ids}, "
            f"got {list(record.sensor_ids)}"
        )
    N = len(_targets(scenario))
    if record.observed is None:
        raise ValueError("record.observed: the per-target bound needs the (K, S, N) array")
    observed = np.asarray(record.observed)
    if observed.shape != (K, S, N) or observed.dtype != bool:
        raise ValueError(
            f"record.observed must be a bool array (K, S, N) = ({K}, {S}, {N}), "
            f"got {observed.dtype} {observed.shape}"
        )
    return observed


def _measurement_information(
    sensors: list[ClutteredSensor], states: FloatArray, looked: np.ndarray, X: FloatArray
) -> FloatArray:
    """J_Z ``(4, 4)`` of the sensors with ``looked`` ``(S,)`` at pv ``states`` ``(S, 4)``."""
    idx = np.flatnonzero(looked)
    if idx.size == 0:
        return np.zeros((4, 4))
    return measurement_information([sensors[i] for i in idx], states[idx], X)


def _target_information(
    target: TargetConfig,
    dt: float,
    alive: np.ndarray,
    J_Z_of: Callable[[int, FloatArray], FloatArray],
    n_samples: int,
    rng: np.random.Generator,
) -> FloatArray:
    """J ``(K, 4, 4)`` of one target at epochs 1..K (NaN where not alive); ``alive``
    ``(K+1,)``; ``J_Z_of(k, X)`` the measurement information at epoch k for samples X."""
    linear = as_linear(build_motion_model(target.motion))
    F, Q = linear.transition_matrix(dt), linear.process_noise(dt)
    C0 = target.prior.covariance()
    epochs = np.flatnonzero(alive)
    out = np.full((alive.size - 1, 4, 4), math.nan)
    if epochs.size == 0:
        return out
    b = int(epochs[0])
    X = gaussian_samples(np.array(target.prior.mean), C0, n_samples, rng)
    J = covariance_bound(C0)  # eq. 4: J_b = C_0^{-1}
    if b >= 1:
        J = J + J_Z_of(b, X)
        out[b - 1] = J
    for k in epochs[1:]:
        X = propagate_samples(X, F, Q, 1, rng)[0]
        J = pcrlb_step(J, F, Q, J_Z_of(int(k), X))
        out[k - 1] = J
    return out


def target_bounds(
    scenario: Scenario,
    record: MultiRunRecord,
    rng: np.random.Generator,
    *,
    n_samples: int = BOUND_SAMPLES,
) -> FloatArray:
    """The PCRLB ``J^-1`` of every target along the run: ``(K, N, 4, 4)`` at epochs 1..K, NaN
    where a target is not alive (recursion in the module docstring).

    Sensor s of ``record.sensor_ids`` (scenario order) measures from its platform's pv in
    ``record.platform_paths`` at that epoch and counts for target n at epoch k only where
    ``record.observed[k-1, s, n]``. Draws from ``rng``, target by target in scenario order:
    ``n_samples`` prior samples at birth, then the process noise of each later epoch (the
    order of ``bounds.pcrlb.gaussian_samples`` and ``propagate_samples``).
    """
    alive = alive_mask(scenario, record)
    K = alive.shape[0] - 1
    sensors, columns = bound_sensors(scenario)
    observed = _check_observed(scenario, record, K, len(sensors))
    paths = np.asarray(record.platform_paths, dtype=float)[:, columns, :]  # (K+1, S, 4)
    J = np.full((K, alive.shape[1], 4, 4), math.nan)
    for n, target in enumerate(_targets(scenario)):

        def J_Z_of(k: int, X: FloatArray, n: int = n) -> FloatArray:
            return _measurement_information(sensors, paths[k], observed[k - 1, :, n], X)

        J[:, n] = _target_information(target, scenario.dt, alive[:, n], J_Z_of, n_samples, rng)
    bound = np.full_like(J, math.nan)
    held = alive[1:]
    bound[held] = covariance_bound(J[held])
    return bound
