"""The evaluation of one run, the same for every scene: each target's error against its PCRLB,
GOSPA / OSPA over time, track breaks and swaps.

**Held.** Target n is held at epoch k by a reported track (a confirmed one the tracker does
not withhold, ``tracker.tracks.report``): under known association (one
target, no clutter) the track its prior started; otherwise the track paired with it in that
epoch's optimal GOSPA assignment with alpha = 2 (pairs closer than the cut-off ``c``,
Rahmathullah, Garcia-Fernandez & Svensson 2017, Proposition 1). Its error is that track's pv
mean minus the truth; NaN where not held.

**GOSPA / OSPA** at k = 1..K between reported tracks' and alive targets' positions
(``scenario.evaluation``'s ``c``, ``p``, alpha): GOSPA (Rahmathullah et al. eq. 1) with its
alpha = 2 split (eq. 2) into localisation, missed and false, and OSPA (Schuhmacher, Vo & Vo
2008, eq. 3).

**Breaks and swaps** between epochs k-1 and k: a swap, target n held by track a then by track
b (an exchange counts two: CLEAR MOT's identity switches, Bernardin & Stiefelhagen 2008); a
break, target n held then alive and not held (a fragmentation, Li, Huang & Nevatia 2009). A
target that dies is not broken; one held again later is not a swap.

**The PCRLB of each target** from its birth epoch b, for linear dynamics (NaN otherwise;
Hernandez 2004 eq. 3-4, 8-9)::

    J_b     = C_0^{-1} + J_Z(b)                                (J_Z(0) = 0: no scan at epoch 0)
    J_{k+1} = (Q + F J_k^{-1} F^T)^{-1} + J_Z(k+1),   b <= k < last alive epoch,

C_0 the target's prior at birth, J_Z the sum over the sensors that scanned at k of
E[q H^T R^-1 H] over samples of the prior pushed through the noisy dynamics (Hernandez sec.
3.2; one generator stream, targets in scenario order). q is ``pd`` under known association,
else the information reduction factor of the clutter and gate (Niu, Willett & Bar-Shalom 2001;
Hernandez, Farina & Ristic 2006; :class:`activetrack.models.clutter.ClutteredSensor`). A beam
counts for a target only at the epochs it held the true position (it points at a track).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from activetrack.arraytypes import FloatArray
from activetrack.bounds.pcrlb import (
    covariance_bound,
    gaussian_samples,
    measurement_information,
    pcrlb_step,
    propagate_step,
)
from activetrack.checks import require_finite
from activetrack.closed_loop.components import scene_sensors, scene_targets
from activetrack.closed_loop.record import RunRecord
from activetrack.data import TrackSet
from activetrack.linalg import psd_sqrt
from activetrack.metrics import GospaResult, gospa, ospa
from activetrack.models.base import as_linear
from activetrack.models.clutter import ClutteredSensor
from activetrack.scenarios.build import build_motion_model
from activetrack.scenarios.schema import EvaluationConfig, Scenario, TargetConfig

__all__ = [
    "BOUND_SAMPLES",
    "NOT_HELD",
    "EpochAssessment",
    "EpochAssessor",
    "RunEvaluation",
    "TargetBound",
    "alive_mask",
    "count_breaks_swaps",
    "epoch_gospa",
    "evaluate_run",
    "held_tracks",
    "reported_positions",
    "target_bounds",
]

# Monte Carlo samples of each target's prior for the bound (Hernandez used 1,000).
BOUND_SAMPLES = 1000
NOT_HELD = -1  # in held_tracks: the target has no track (BeamCommand's "no track" too)


@dataclass(frozen=True)
class RunEvaluation:
    """The evaluation of one run at epochs 1..K, N targets in scenario order. ``bound`` is NaN
    where not alive or for nonlinear dynamics; ``localisation``, ``missed`` and ``false`` are
    GOSPA's alpha = 2 split (:class:`~activetrack.metrics.GospaResult`)."""

    time: np.ndarray  # (K,) [s]
    error: np.ndarray  # (K, N, 4)
    bound: np.ndarray  # (K, N, 4, 4)
    held: np.ndarray  # (K, N) int
    alive: np.ndarray  # (K, N) bool
    gospa: np.ndarray  # (K,) [m]
    localisation: np.ndarray  # (K,) [m^p]
    missed: np.ndarray  # (K,) int
    false: np.ndarray  # (K,) int
    ospa: np.ndarray  # (K,) [m]
    breaks: int
    swaps: int

    @property
    def mean_gospa(self) -> float:
        """GOSPA averaged over epochs 1..K [m]."""
        return float(np.mean(self.gospa))

    @property
    def held_fraction(self) -> np.ndarray:
        """``(N,)``: the fraction of a target's alive epochs in 1..K at which it was held (NaN
        if it was never alive there)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return (self.held != NOT_HELD).sum(axis=0) / self.alive.sum(axis=0)


# --- the record against the scenario ---------------------------------------------------------


def _check_shapes(scenario: Scenario, record: RunRecord) -> int:
    """K (epochs 1..K) of a record whose arrays fit the scenario; ValueError otherwise."""
    targets = scene_targets(scenario)
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
    ids = [s.id for p in scenario.platforms for s in p.sensors]
    if tuple(record.sensor_ids) != tuple(ids):
        raise ValueError(
            f"record.sensor_ids must be the scenario's sensors in order {ids}, "
            f"got {list(record.sensor_ids)}"
        )
    for name, shape in (("looked", (K, len(ids))), ("observed", (K, len(ids), N))):
        value = getattr(record, name)
        if value is None or np.asarray(value).shape != shape or np.asarray(value).dtype != bool:
            raise ValueError(f"record.{name} must be a bool array {shape}, got {value!r}"[:200])
    return K


def alive_mask(scenario: Scenario, record: RunRecord) -> np.ndarray:
    """``(K+1, N)`` bool: target n alive at epoch k (its truth row is not NaN). ValueError
    naming the field unless the record fits the scenario (shapes, target and sensor order) and
    each target is alive exactly for epochs ``birth <= k < death``."""
    K = _check_shapes(scenario, record)
    truth = np.asarray(record.truth, dtype=float)
    alive = ~np.isnan(truth[..., 0])
    if not np.isfinite(truth[alive]).all():
        raise ValueError("record.truth: an alive target's row must be finite (all 4 entries)")
    k = np.arange(K + 1)
    for n, t in enumerate(scene_targets(scenario)):
        death = math.inf if t.death is None else t.death
        expected = (k >= t.birth) & (k < death)
        if not np.array_equal(alive[:, n], expected):
            raise ValueError(
                f"record.truth: target {t.id!r} must be alive (not NaN) exactly at epochs "
                f"birth <= k < death ({t.birth}, {t.death}), got alive at "
                f"{np.flatnonzero(alive[:, n]).tolist()}"
            )
    return alive


# --- who holds whom --------------------------------------------------------------------------


@dataclass(frozen=True)
class EpochAssessment:
    """One epoch's scores: GOSPA (the scenario's alpha) and its alpha = 2 split, OSPA, and the
    id of the confirmed track holding each target ``(N,)`` (:data:`NOT_HELD` where none)."""

    gospa: float
    localisation: float
    missed: int
    false: int
    ospa: float
    held: np.ndarray


def reported_positions(tracks: TrackSet, k: int = 0) -> FloatArray:
    """``(M, 2)`` x, y of the tracks the tracker reports (its confirmed tracks but those it
    withholds, ``tracker.tracks.report``); ValueError for a mean that is not finite."""
    Y = np.array([np.asarray(t.mean)[[0, 2]] for t in tracks.reported], dtype=float).reshape(-1, 2)
    if not np.isfinite(Y).all():
        raise ValueError(f"record.tracks[{k}]: a confirmed track's mean must be finite")
    return Y


def epoch_gospa(
    X: FloatArray, Y: FloatArray, evaluation: EvaluationConfig
) -> tuple[float, GospaResult]:
    """GOSPA between targets ``X`` ``(N, 2)`` and tracks ``Y`` ``(M, 2)`` with the
    evaluation's cut-off, order and alpha, and its alpha = 2 split (localisation, missed,
    false, assignment; Rahmathullah et al. 2017, eq. 1-2)."""
    ev = evaluation
    split = gospa(X, Y, ev.cutoff, ev.order, 2.0)
    distance = split.distance
    if ev.alpha != 2.0:
        distance = gospa(X, Y, ev.cutoff, ev.order, ev.alpha).distance
    return distance, split


class EpochAssessor:
    """Scores one epoch at a time, for the batch evaluation and the graph's live evaluator."""

    def __init__(self, scenario: Scenario):
        self.evaluation = scenario.evaluation
        self.known = scenario.known_association
        self.index = {t.id: n for n, t in enumerate(scene_targets(scenario))}

    def __call__(self, truth: FloatArray, tracks: TrackSet, k: int = 0) -> EpochAssessment:
        """``truth`` ``(N, 4)`` pv of every target at the epoch (NaN where not alive) and the
        tracker's output there."""
        truth = np.asarray(truth, dtype=float)
        targets = np.flatnonzero(~np.isnan(truth[:, 0]))
        X = truth[targets][:, [0, 2]]
        reported = tracks.reported
        Y = reported_positions(tracks, k)
        distance, split = epoch_gospa(X, Y, self.evaluation)
        held = np.full(truth.shape[0], NOT_HELD, dtype=int)
        if self.known:  # the track is the target's by construction
            for t in reported:
                n = self.index.get(t.origin)
                if n is None:
                    raise ValueError(
                        f"record.tracks[{k}]: track {t.track_id} has origin {t.origin!r}; with "
                        f"known association every track is a target's {sorted(self.index)}"
                    )
                held[n] = t.track_id
        else:
            for i, j in split.assignment:
                held[targets[i]] = reported[j].track_id
        return EpochAssessment(
            distance,
            split.localisation,
            int(split.missed),
            int(split.false_tracks),
            ospa(X, Y, self.evaluation.cutoff, self.evaluation.order),
            held,
        )


def _epochs(
    scenario: Scenario, record: RunRecord, alive: np.ndarray
) -> tuple[FloatArray, np.ndarray]:
    """Per epoch 1..K: ``(5, K)`` GOSPA, localisation, missed, false, OSPA; and ``(K, N)`` the
    id of the track holding each target (:data:`NOT_HELD` where none does)."""
    K, N = alive.shape[0] - 1, alive.shape[1]
    assess = EpochAssessor(scenario)
    held = np.full((K, N), NOT_HELD, dtype=int)
    series = np.zeros((5, K))
    truth = np.asarray(record.truth, dtype=float)
    for k in range(1, K + 1):
        a = assess(truth[k], record.tracks[k], k)
        series[:, k - 1] = (a.gospa, a.localisation, a.missed, a.false, a.ospa)
        held[k - 1] = a.held
    return series, held


def held_tracks(scenario: Scenario, record: RunRecord) -> np.ndarray:
    """``(K, N)``: the confirmed track holding target n at epoch k = 1..K, or :data:`NOT_HELD`."""
    return _epochs(scenario, record, alive_mask(scenario, record))[1]


def count_breaks_swaps(held: np.ndarray, alive: np.ndarray) -> tuple[int, int]:
    """(breaks, swaps) of ``held`` ``(K, N)`` with ``alive`` ``(K, N)`` (module docstring)."""
    held = np.asarray(held)
    alive = np.asarray(alive, dtype=bool)
    if held.shape != alive.shape or held.ndim != 2:
        raise ValueError(f"held and alive must both be (K, N), got {held.shape} and {alive.shape}")
    before, now = held[:-1], held[1:]
    was_held = before != NOT_HELD
    is_held = now != NOT_HELD
    swaps = was_held & is_held & (now != before)
    breaks = was_held & ~is_held & alive[1:]
    return int(breaks.sum()), int(swaps.sum())


def _errors(record: RunRecord, held: np.ndarray) -> np.ndarray:
    """``(K, N, 4)``: the holding track's pv mean minus the truth, NaN where not held."""
    truth = np.asarray(record.truth, dtype=float)[1:]
    out = np.full((*held.shape, 4), math.nan)
    for k, row in enumerate(held):
        means = {t.track_id: t.mean for t in record.tracks[k + 1].reported}
        for n in np.flatnonzero(row != NOT_HELD):
            out[k, n] = np.asarray(means[int(row[n])]) - truth[k, n]
    return out


# --- the bound -------------------------------------------------------------------------------


class TargetBound:
    """The PCRLB of one target (module docstring) one epoch at a time, with the draws of
    :func:`target_bounds` (the live view's bound equals the summary's)."""

    def __init__(
        self,
        target: TargetConfig,
        sensors: list[ClutteredSensor],
        dt: float,
        rng: np.random.Generator,
        n_samples: int = BOUND_SAMPLES,
    ):
        model = build_motion_model(target.motion)
        self.linear = model.is_linear
        self.sensors = sensors
        self.rng = rng
        self.n_samples = n_samples
        self.birth, self.death = target.birth, target.death
        self.epoch = 0
        self.mean = np.array(target.prior.mean, dtype=float)
        self.C0 = target.prior.covariance()
        self.X: FloatArray | None = None
        self.J: FloatArray | None = None
        self.S: FloatArray | None = None  # psd_sqrt(Q), taken at the first propagation
        if self.linear:
            linear = as_linear(model)
            self.F, self.Q = linear.transition_matrix(dt), linear.process_noise(dt)
            if self.birth == 0:
                self._born()

    def _born(self) -> None:
        self.X = gaussian_samples(self.mean, self.C0, self.n_samples, self.rng)
        self.J = np.linalg.inv(self.C0)  # eq. 4: J_b = C_0^{-1}

    def _information(self, sensor_pv: FloatArray, counts: np.ndarray) -> FloatArray:
        idx = np.flatnonzero(counts)
        if idx.size == 0:
            return np.zeros((4, 4))
        chosen = [self.sensors[i] for i in idx]
        assert self.X is not None
        return measurement_information(chosen, np.asarray(sensor_pv)[idx], self.X)

    def _propagate(self, X: FloatArray) -> FloatArray:
        """``propagate_samples(X, F, Q, 1, rng)[0]``: its checks and its draws, with the root
        of Q taken once (a third of the step)."""
        require_finite("target_samples", X)
        if self.S is None:
            require_finite("F", self.F)
            self.S = psd_sqrt("Q", np.asarray(self.Q, dtype=float))
        return propagate_step(X, self.F, self.S, self.rng)

    def information(self, sensor_pv: FloatArray, counts: np.ndarray) -> FloatArray | None:
        """J ``(4, 4)`` at the next epoch from the sensors' pv there ``(S, 4)`` and which count
        ``(S,)``; None while the target is not alive or for nonlinear dynamics."""
        self.epoch += 1
        k = self.epoch
        alive = k >= self.birth and (self.death is None or k < self.death)
        if not (self.linear and alive):
            return None
        if self.J is None:  # born now
            self._born()
            assert self.J is not None
            self.J = self.J + self._information(sensor_pv, counts)
        else:
            assert self.X is not None
            self.X = self._propagate(self.X)
            self.J = pcrlb_step(self.J, self.F, self.Q, self._information(sensor_pv, counts))
        return self.J

    def step(self, sensor_pv: FloatArray, counts: np.ndarray) -> FloatArray:
        """J^-1 ``(4, 4)`` at the next epoch, NaN where there is none."""
        J = self.information(sensor_pv, counts)
        return np.full((4, 4), math.nan) if J is None else covariance_bound(J)


def bound_counts(
    sensors: list[ClutteredSensor], looked: np.ndarray, observed: np.ndarray
) -> np.ndarray:
    """``(..., S, N)``: sensor s counts for target n where it scanned, and, for a steerable
    beam, held the target's true position (module docstring). ``looked`` ``(..., S)``,
    ``observed`` ``(..., S, N)``."""
    steerable = np.array([s.steerable for s in sensors], dtype=bool)
    looked = np.asarray(looked, dtype=bool)[..., None]
    return looked & np.where(steerable[:, None], np.asarray(observed, dtype=bool), True)


def target_bounds(
    scenario: Scenario,
    record: RunRecord,
    rng: np.random.Generator,
    *,
    n_samples: int = BOUND_SAMPLES,
) -> FloatArray:
    """The PCRLB ``J^-1`` ``(K, N, 4, 4)`` at epochs 1..K, NaN where a target is not alive.
    Draws from ``rng`` target by target: ``n_samples`` prior samples at birth, then each later
    epoch's process noise."""
    alive_mask(scenario, record)
    K = record.steps
    sensors, columns = bound_sensors(scenario)
    paths = np.asarray(record.platform_paths, dtype=float)[:, columns, :]  # (K+1, S, 4)
    looked, observed = np.asarray(record.looked), np.asarray(record.observed)  # checked above
    counts = bound_counts(sensors, looked, observed)  # (K, S, N)
    out = np.full((K, len(record.target_ids), 4, 4), math.nan)
    for n, target in enumerate(scene_targets(scenario)):
        bound = TargetBound(target, sensors, scenario.dt, rng, n_samples)
        J = [bound.information(paths[k], counts[k - 1, :, n]) for k in range(1, K + 1)]
        alive = [k for k, j in enumerate(J) if j is not None]
        if alive:  # one batched inverse per target
            out[alive, n] = covariance_bound(np.stack([j for j in J if j is not None]))
    return out


def bound_sensors(scenario: Scenario) -> tuple[list[ClutteredSensor], list[int]]:
    """The scene's sensors in scenario order and their platforms' indices."""
    platform_ids = [p.id for p in scenario.platforms]
    scene = list(scene_sensors(scenario).values())  # (platform id, sensor)
    return [sensor for _, sensor in scene], [platform_ids.index(pid) for pid, _ in scene]


# --- one run -----------------------------------------------------------------------------------


def evaluate_run(
    scenario: Scenario,
    record: RunRecord,
    rng: np.random.Generator,
    *,
    n_samples: int = BOUND_SAMPLES,
) -> RunEvaluation:
    """Each target's error and bound, GOSPA / OSPA, breaks and swaps of one run; ``rng`` draws
    only the bound's samples. ValueError when the record does not fit the scenario."""
    alive = alive_mask(scenario, record)
    K = alive.shape[0] - 1
    series, held = _epochs(scenario, record, alive)
    breaks, swaps = count_breaks_swaps(held, alive[1:])
    return RunEvaluation(
        time=np.array([record.tracks[k].time for k in range(1, K + 1)], dtype=float),
        error=_errors(record, held),
        bound=target_bounds(scenario, record, rng, n_samples=n_samples),
        held=held,
        alive=alive[1:],
        gospa=series[0],
        localisation=series[1],
        missed=series[2].astype(int),
        false=series[3].astype(int),
        ospa=series[4],
        breaks=breaks,
        swaps=swaps,
    )
