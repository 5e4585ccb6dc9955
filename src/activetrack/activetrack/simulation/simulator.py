"""The simulator: targets born and dying, platform kinematics, scans of unlabelled detections
with clutter, steerable beams, sensor selection and command clamping.

Platforms fly constant-velocity legs between decision epochs; a manoeuvre (heading change,
speed change) applies instantaneously at an epoch (Hernandez sec. 3.3.1). Commands outside a
platform's limits are clamped and the clamp is reported, never silent.

Each epoch every looking sensor scans its field of view (:meth:`ClutteredSensor.field_of_view`:
a fixed sector, all around, or a steerable beam pointed by the planner): each alive target is
detected inside it and the detection ranges with the sensor's ``pd``
(:meth:`ClutteredSensor.detect`); Poisson false alarms are added uniformly over the field of
view (:meth:`ClutteredSensor.sample_clutter`); the detections are shuffled, so their order says
nothing about their origin, and reach the tracker without labels. The labels are kept in
:class:`~activetrack.data.ScanTruth` for evaluation only. One target and no clutter is the
simplest case: a scan of at most one detection, the papers' measurement.

Random draws (:mod:`activetrack.simulation.streams`): with ``common`` streams (the default)
each target's motion, each sensor's detections and noise and each sensor's clutter at each
epoch have their own stream, so the world does not depend on the policy. With ``sequential``
streams all come from the one generator in this order each epoch: the targets' motion
(scenario order; a target born this epoch draws its start from its prior), then per looking
sensor (scenario order) for each alive target (scenario order) the detection draw (one whether
the target is in view or not) and, if detected, its measurement noise; then the clutter and the
shuffle (no draw for fewer than two detections).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from activetrack.angles import wrap_angle
from activetrack.data import (
    BeamCommand,
    Command,
    PlatformSnapshot,
    Scan,
    ScanTruth,
    TruthSet,
    heading_speed,
)
from activetrack.models.base import MotionModel
from activetrack.models.clutter import ClutteredSensor
from activetrack.models.fov import FieldOfView
from activetrack.simulation.streams import RandomStreams, StreamsMode

__all__ = ["ApplyResult", "ManoeuvreLimits", "SimPlatform", "SimTarget", "Simulator"]


class ManoeuvreLimits(Protocol):
    """A platform's limits (a scenario's ``limits:``, :class:`activetrack.scenarios.schema.
    ManoeuvreLimits`, or any object with them): the largest heading and speed changes per
    decision interval dt, and the speed range."""

    @property
    def v_min(self) -> float: ...
    @property
    def v_max(self) -> float: ...
    def per_epoch(self, dt: float) -> tuple[float, float]: ...


# Excess over a limit below this (relative) is float round-off, not a clamp worth reporting.
_CLAMP_SLACK = 1e-9


@dataclass(frozen=True)
class SimTarget:
    """A target of the scene: its motion ``model``, its truth at ``birth`` (``initial_state``,
    or a draw from its prior ``N(prior_mean, prior_cov)``) and the epochs it exists,
    ``birth <= k < death`` (None: to the end)."""

    target_id: str
    model: MotionModel
    prior_mean: np.ndarray
    prior_cov: np.ndarray
    initial_state: np.ndarray | None = None
    birth: int = 0
    death: int | None = None

    def draw_start(self, rng: np.random.Generator) -> np.ndarray:
        if self.initial_state is not None:
            return np.array(self.initial_state, dtype=float)
        L = np.linalg.cholesky(self.prior_cov)
        return np.array(self.prior_mean) + L @ rng.standard_normal(len(self.prior_mean))


@dataclass(frozen=True)
class SimPlatform:
    """A platform of the scene: its pv at epoch 0, its manoeuvre ``limits`` (None: not
    controllable) and its sensors, ``(sensor id, sensor in the scene)`` in scenario order."""

    platform_id: str
    initial_pv: np.ndarray
    limits: ManoeuvreLimits | None
    sensors: tuple[tuple[str, ClutteredSensor], ...]


@dataclass
class _Platform:
    id: str
    pv: np.ndarray
    limits: ManoeuvreLimits | None
    sensor_ids: tuple[str, ...]

    @property
    def controllable(self) -> bool:
        return self.limits is not None


@dataclass(frozen=True)
class ApplyResult:
    """Outcome of applying one command: what was applied and, if clamped, why."""

    command: Command
    clamped: bool
    message: str = ""


class Simulator:
    """Truth of every target and the platforms for one run; draws only from ``rng`` (its
    seed sequence keys the ``common`` streams). ``advance`` returns the epoch's scans;
    :attr:`last_truth` their labels, :attr:`looked` ``(S,)`` which sensors scanned and
    :attr:`last_observed` ``(S, N)`` which sensor had which alive target inside its field of
    view and detection ranges."""

    def __init__(
        self,
        targets: Sequence[SimTarget],
        platforms: Sequence[SimPlatform],
        dt: float,
        steps: int,
        rng: np.random.Generator,
        random_streams: StreamsMode = "common",
    ):
        self.streams = RandomStreams(rng, random_streams)
        self.dt = float(dt)
        self.steps = int(steps)
        self.targets = tuple(targets)
        self.states: list[np.ndarray | None] = [
            t.draw_start(self.streams.target(i)) if t.birth == 0 else None
            for i, t in enumerate(self.targets)
        ]
        self.platforms: dict[str, _Platform] = {}
        # sensor id -> (platform id, sensor), scenario order
        self.sensors: dict[str, tuple[str, ClutteredSensor]] = {}
        self.pointing: dict[str, float] = {}  # steerable beams, world bearing
        for p in platforms:
            pv = np.array(p.initial_pv, dtype=float)
            self.platforms[p.platform_id] = _Platform(
                p.platform_id, pv, p.limits, tuple(sid for sid, _ in p.sensors)
            )
            for sid, sensor in p.sensors:
                self.sensors[sid] = (p.platform_id, sensor)
                if sensor.steerable:  # a beam starts along its platform's heading
                    self.pointing[sid] = math.atan2(pv[3], pv[1])
        self.epoch = 0
        self.selected: tuple[str, ...] | None = None  # None: every sensor measures
        self.measuring = {pid: True for pid in self.platforms}  # stop-and-measure gating
        self.last_truth: list[ScanTruth] = []
        self.looked = np.zeros(len(self.sensors), dtype=bool)
        self.last_observed = np.zeros((len(self.sensors), len(self.targets)), dtype=bool)

    # --- what is there -----------------------------------------------------------------------
    @property
    def time(self) -> float:
        return self.epoch * self.dt

    @property
    def finished(self) -> bool:
        return self.epoch >= self.steps

    @property
    def target_ids(self) -> tuple[str, ...]:
        return tuple(t.target_id for t in self.targets)

    @property
    def controllable_ids(self) -> tuple[str, ...]:
        return tuple(p.id for p in self.platforms.values() if p.controllable)

    @property
    def steerable_ids(self) -> tuple[str, ...]:
        return tuple(self.pointing)

    def truth_array(self) -> np.ndarray:
        """Every target's pv ``(N, 4)`` in scenario order, NaN where not alive."""
        out = np.full((len(self.targets), 4), math.nan)
        for i, (t, x) in enumerate(zip(self.targets, self.states, strict=True)):
            if x is not None:
                out[i] = t.model.kinematics(x)
        return out

    def truth_set(self) -> TruthSet:
        """The alive targets' ids, pv ``(N_alive, 4)`` and model states."""
        keep = [i for i, x in enumerate(self.states) if x is not None]
        return TruthSet(
            self.epoch,
            self.time,
            tuple(self.targets[i].target_id for i in keep),
            self.truth_array()[keep].reshape(-1, 4),
            tuple(np.array(self.states[i]) for i in keep),
            tuple(tuple(self.targets[i].model.state_names) for i in keep),
        )

    def platform_snapshots(self) -> list[PlatformSnapshot]:
        out = []
        for p in self.platforms.values():
            heading, speed = heading_speed(p.pv)
            kinds = tuple(self.sensors[s][1].kind for s in p.sensor_ids)
            out.append(
                PlatformSnapshot(
                    p.id, self.epoch, self.time, p.pv.copy(), heading, speed, p.sensor_ids, kinds
                )
            )
        return out

    # --- the epoch ---------------------------------------------------------------------------
    def advance(self) -> list[Scan]:
        """Simulate epoch k+1: targets, platform legs, then one scan per looking sensor."""
        if self.finished:
            raise RuntimeError(f"the scenario has only {self.steps} steps")
        self.epoch += 1
        self._move_targets()
        self._move_platforms()
        truth = self.truth_array()
        alive = np.flatnonzero(~np.isnan(truth[:, 0]))
        scans, labels = [], []
        self.looked = np.zeros(len(self.sensors), dtype=bool)
        self.last_observed = np.zeros((len(self.sensors), len(self.targets)), dtype=bool)
        for j, (sensor_id, (platform_id, sensor)) in enumerate(self.sensors.items()):
            if self.selected is not None and sensor_id not in self.selected:
                continue
            if not self.measuring[platform_id]:
                continue
            s_pv = self.platforms[platform_id].pv.copy()
            scan, scan_truth = self._scan(j, sensor_id, sensor, s_pv, truth, alive)
            self.looked[j] = True
            scans.append(scan)
            labels.append(scan_truth)
        self.last_truth = labels
        return scans

    def _move_targets(self) -> None:
        k = self.epoch
        for i, t in enumerate(self.targets):
            x = self.states[i]
            if t.death is not None and k >= t.death:
                self.states[i] = None
            elif x is not None:
                self.states[i] = t.model.sample(x, self.dt, self.streams.target(i))
            elif t.birth == k:
                self.states[i] = t.draw_start(self.streams.target(i))

    def _move_platforms(self) -> None:
        """Every platform flies its constant-velocity leg to the next epoch."""
        for p in self.platforms.values():
            p.pv = p.pv + self.dt * np.array([p.pv[1], 0.0, p.pv[3], 0.0])

    def _scan(
        self,
        j: int,
        sensor_id: str,
        sensor: ClutteredSensor,
        s_pv: np.ndarray,
        truth: np.ndarray,
        alive: np.ndarray,
    ) -> tuple[Scan, ScanTruth]:
        fov = sensor.field_of_view(s_pv, self.pointing.get(sensor_id))
        if alive.size:
            X = truth[alive]
            self.last_observed[j, alive] = fov.contains(X, s_pv) & sensor.in_range(X, s_pv)
        rows, names = self._detections(j, sensor, s_pv, truth, alive, fov)
        rng = self.streams.clutter(j, self.epoch)
        clutter = sensor.sample_clutter(fov, rng)
        Z = np.vstack([np.reshape(rows, (-1, sensor.dim_z)), clutter])
        all_names = names + [""] * len(clutter)
        order = rng.permutation(len(Z))  # no draw for 0 or 1 detections
        scan = Scan(sensor_id, self.epoch, self.time, s_pv, Z[order], fov)
        return scan, ScanTruth(sensor_id, self.epoch, tuple(all_names[i] for i in order))

    def _detections(
        self,
        j: int,
        sensor: ClutteredSensor,
        s_pv: np.ndarray,
        truth: np.ndarray,
        alive: np.ndarray,
        fov: FieldOfView,
    ) -> tuple[list, list[str]]:
        """The target-originated rows ``z`` and their target ids. Common streams: one detection
        draw and one noise draw for every alive target, all at once, detected or not;
        sequential: per target, noise only if detected."""
        rng = self.streams.detection(j, self.epoch)
        if self.streams.common:
            if not alive.size:
                return [], []
            X = truth[alive]
            hit = np.asarray(sensor.detect(X, s_pv, rng, fov), dtype=bool).reshape(-1)
            Z = np.asarray(sensor.sample(X, s_pv, rng), dtype=float).reshape(len(alive), -1)
            return list(Z[hit]), [self.targets[i].target_id for i in alive[hit]]
        rows, names = [], []
        for i in alive:
            if sensor.detect(truth[i], s_pv, rng, fov):
                rows.append(sensor.sample(truth[i], s_pv, rng))
                names.append(self.targets[i].target_id)
        return rows, names

    # --- commands ----------------------------------------------------------------------------
    def apply_command(self, cmd: Command) -> ApplyResult:
        """Apply a manoeuvre for the leg starting now, within the platform's limits.

        Raises ValueError for an unknown or uncontrollable platform or a command for another
        epoch than the current one (the caller rejects and counts it).
        """
        p = self.platforms.get(cmd.platform_id)
        if p is None:
            raise ValueError(
                f"platform_id must be one of {sorted(self.platforms)}, got {cmd.platform_id!r}"
            )
        if p.limits is None:
            raise ValueError(f"platform_id {cmd.platform_id!r} is not controllable")
        if cmd.epoch != self.epoch:
            raise ValueError(f"epoch must be the current epoch {self.epoch}, got {cmd.epoch}")
        if not (math.isfinite(cmd.heading_change) and math.isfinite(cmd.speed_change)):
            raise ValueError("heading_change and speed_change must be finite")
        dpsi_max, dv_max = p.limits.per_epoch(self.dt)
        heading, speed = heading_speed(p.pv)
        notes = []
        dpsi = float(np.clip(cmd.heading_change, -dpsi_max, dpsi_max))
        if abs(dpsi - cmd.heading_change) > _CLAMP_SLACK * max(1.0, dpsi_max):
            notes.append(f"heading_change {cmd.heading_change:.6g} clamped to +-{dpsi_max:.6g}")
        dv = float(np.clip(cmd.speed_change, -dv_max, dv_max))
        if abs(dv - cmd.speed_change) > _CLAMP_SLACK * max(1.0, dv_max):
            notes.append(f"speed_change {cmd.speed_change:.6g} clamped to +-{dv_max:.6g}")
        lo, hi = p.limits.v_min, p.limits.v_max
        new_speed = float(np.clip(speed + dv, lo, hi))
        if abs(new_speed - (speed + dv)) > _CLAMP_SLACK * max(1.0, hi):
            notes.append(f"speed {speed + dv:.6g} clamped to [{lo:.6g}, {hi:.6g}]")
        new_heading = float(wrap_angle(heading + dpsi))
        p.pv = np.array(
            [p.pv[0], new_speed * math.cos(new_heading), p.pv[2], new_speed * math.sin(new_heading)]
        )
        if cmd.take_measurement is not None:
            self.measuring[cmd.platform_id] = bool(cmd.take_measurement)
        applied = Command(
            cmd.platform_id,
            cmd.epoch,
            dpsi,
            new_speed - speed,
            new_heading,
            new_speed,
            cmd.take_measurement,
            cmd.waypoint,
        )
        return ApplyResult(applied, bool(notes), "; ".join(notes))

    def apply_beam(self, beam: BeamCommand) -> None:
        """Point a steerable sensor's beam for the next epoch (ValueError for another epoch,
        an unknown or non-steerable sensor, or a non-finite bearing)."""
        if beam.sensor_id not in self.pointing:
            steerable = sorted(self.pointing)
            raise ValueError(
                f"sensor_id must be a steerable sensor, one of {steerable}, got {beam.sensor_id!r}"
            )
        if beam.epoch != self.epoch:
            raise ValueError(f"epoch must be the current epoch {self.epoch}, got {beam.epoch}")
        if not math.isfinite(beam.bearing):
            raise ValueError(f"bearing must be finite, got {beam.bearing!r}")
        self.pointing[beam.sensor_id] = math.remainder(beam.bearing, 2.0 * math.pi)

    def apply_selection(self, sensor_ids: Sequence[str] | None) -> None:
        """Only these sensors measure from the next epoch on (None: all of them)."""
        if sensor_ids is None:
            self.selected = None
            return
        unknown = [s for s in sensor_ids if s not in self.sensors]
        if unknown:
            raise ValueError(f"sensor ids must be among {sorted(self.sensors)}, got {unknown}")
        self.selected = tuple(sensor_ids)
