"""The multi-target simulator: targets born and dying, unlabelled detections with clutter, beams.

Platforms, their legs and command clamping are the single-target simulator's
(:class:`activetrack.closed_loop.simulator.Simulator`). Each epoch every sensor scans its field of
view (:meth:`ClutteredSensor.field_of_view`: a fixed sector, all around, or a steerable beam
pointed by the planner): each alive target inside it and inside the detection ranges is
detected with the sensor's ``pd``; Poisson false alarms are added uniformly over the field of
view (:meth:`ClutteredSensor.sample_clutter`); the detections are shuffled, so their order says
nothing about their origin, and reach the tracker without labels. The labels are kept in
:class:`ScanTruth` for evaluation only.

Random draws, all from the simulator's generator, in this order each epoch: the targets' motion
(scenario order; a target born this epoch draws its start from its prior), then per sensor
(scenario order) the detection draws and measurement noise of each target in view, the
clutter, and the shuffle.
"""

from __future__ import annotations

import math

import numpy as np

from activetrack.closed_loop.simulator import Simulator
from activetrack.models.clutter import ClutteredSensor
from activetrack.multitarget.data import BeamCommand, Scan, ScanTruth, TruthSet
from activetrack.scenarios.build import build_motion_model, build_scan_sensors
from activetrack.scenarios.schema import Scenario, TargetConfig

__all__ = ["MultiTargetSimulator"]


def _draw_start(target: TargetConfig, rng: np.random.Generator) -> np.ndarray:
    if target.initial_state is not None:
        return np.array(target.initial_state, dtype=float)
    L = np.linalg.cholesky(target.prior.covariance())
    return np.array(target.prior.mean) + L @ rng.standard_normal(len(target.prior.mean))


class MultiTargetSimulator(Simulator):
    """Truth of every target and the platforms for one multi-target run; draws only from
    ``rng``. ``advance`` returns the epoch's scans; :attr:`last_truth` their labels and
    :attr:`last_observed` ``(S, N)`` which sensor had which alive target in view."""

    def __init__(self, scenario: Scenario, rng: np.random.Generator):
        if scenario.targets is None:
            raise ValueError("targets: a multi-target scenario needs a targets: list")
        self.scenario = scenario
        self.rng = rng
        self.dt = scenario.dt
        self.targets = tuple(scenario.targets)
        self.models = tuple(build_motion_model(t.motion) for t in self.targets)
        self.model = self.models[0]
        self._init_platforms(scenario)
        self.scan_sensors = {sid: m for sid, (_, m) in build_scan_sensors(scenario).items()}
        # Steerable beams start along their platform's heading.
        self.pointing: dict[str, float] = {}
        for p in scenario.platforms:
            heading = math.atan2(p.initial_state[3], p.initial_state[1])
            for s in p.sensors:
                if s.beam_width is not None:
                    self.pointing[s.id] = heading
        self.states: list[np.ndarray | None] = [
            _draw_start(t, rng) if t.birth == 0 else None for t in self.targets
        ]
        self.last_truth: list[ScanTruth] = []
        self.last_observed = np.zeros((len(self.scan_sensors), len(self.targets)), dtype=bool)

    @property
    def target_ids(self) -> tuple[str, ...]:
        return tuple(t.id for t in self.targets)

    def alive(self) -> list[bool]:
        return [x is not None for x in self.states]

    def truth_set(self) -> TruthSet:
        """The alive targets' ids and pv ``(N_alive, 4)``."""
        truth = self.truth_array()
        alive = ~np.isnan(truth[:, 0])
        ids = tuple(t.id for t, keep in zip(self.targets, alive, strict=True) if keep)
        return TruthSet(self.epoch, self.time, ids, truth[alive])

    def truth_array(self) -> np.ndarray:
        """Every target's pv ``(N, 4)`` in scenario order, NaN where not alive."""
        out = np.full((len(self.targets), 4), math.nan)
        for i, (m, x) in enumerate(zip(self.models, self.states, strict=True)):
            if x is not None:
                out[i] = m.kinematics(x)
        return out

    def truth_pv(self) -> np.ndarray:
        return self.truth_array()

    def _move_targets(self) -> None:
        k = self.epoch
        for i, t in enumerate(self.targets):
            x = self.states[i]
            if t.death is not None and k >= t.death:
                self.states[i] = None
            elif x is not None:
                self.states[i] = self.models[i].sample(x, self.dt, self.rng)
            elif t.birth == k:
                self.states[i] = _draw_start(t, self.rng)

    def advance(self) -> list[Scan]:  # type: ignore[override]
        """Simulate epoch k+1: targets, platform legs, then one scan per looking sensor."""
        if self.finished:
            raise RuntimeError(f"the scenario has only {self.scenario.steps} steps")
        self.epoch += 1
        self._move_targets()
        self._move_platforms()
        truth = self.truth_array()
        alive = ~np.isnan(truth[:, 0])
        scans, labels = [], []
        self.last_observed = np.zeros((len(self.scan_sensors), len(self.targets)), dtype=bool)
        for j, (sensor_id, sensor) in enumerate(self.scan_sensors.items()):
            platform_id = self.sensors[sensor_id][0]
            if self.selected is not None and sensor_id not in self.selected:
                continue
            if not self.measuring[platform_id]:
                continue
            s_pv = self.platforms[platform_id].pv.copy()
            scan, truth_labels, seen = self._scan(sensor_id, sensor, s_pv, truth, alive)
            self.last_observed[j] = seen
            scans.append(scan)
            labels.append(truth_labels)
        self.last_truth = labels
        return scans

    def _scan(
        self,
        sensor_id: str,
        sensor: ClutteredSensor,
        s_pv: np.ndarray,
        truth: np.ndarray,
        alive: np.ndarray,
    ) -> tuple[Scan, ScanTruth, np.ndarray]:
        fov = sensor.field_of_view(s_pv, self.pointing.get(sensor_id))
        seen = alive.copy()
        seen[alive] = fov.contains(truth[alive], s_pv) & sensor.in_range(truth[alive], s_pv)
        rows, names = [], []
        for i in np.flatnonzero(seen):
            if self.rng.random() < sensor.pd:
                rows.append(sensor.sample(truth[i], s_pv, self.rng))
                names.append(self.targets[i].id)
        clutter = sensor.sample_clutter(fov, self.rng)
        Z = np.vstack([np.reshape(rows, (-1, sensor.dim_z)), clutter])
        all_names = names + [""] * len(clutter)
        order = self.rng.permutation(len(Z))
        scan = Scan(sensor_id, self.epoch, self.time, s_pv, Z[order], fov)
        return scan, ScanTruth(sensor_id, self.epoch, tuple(all_names[i] for i in order)), seen

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
