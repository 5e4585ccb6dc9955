"""The simulator: ground truth, platform kinematics, measurements and command clamping.

Platforms fly constant-velocity legs between decision epochs; a manoeuvre (heading change,
speed change) applies instantaneously at an epoch (Hernandez sec. 3.3.1). Commands outside a
platform's limits are clamped and the clamp is reported, never silent.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from activetrack.angles import wrap_angle
from activetrack.closed_loop.data import Command, PlatformSnapshot, heading_speed
from activetrack.filters.measurement import Measurement
from activetrack.scenarios.build import build_motion_model, build_sensor
from activetrack.scenarios.schema import ManoeuvreLimits, Scenario

if TYPE_CHECKING:
    from activetrack.models.base import SensorModel

# Excess over a limit below this (relative) is float round-off, not a clamp worth reporting.
_CLAMP_SLACK = 1e-9


@dataclass
class _Platform:
    id: str
    pv: np.ndarray
    controllable: bool
    limits: ManoeuvreLimits | None
    sensor_ids: tuple[str, ...]


@dataclass(frozen=True)
class ApplyResult:
    """Outcome of applying one command: what was applied and, if clamped, why."""

    command: Command
    clamped: bool
    message: str = ""


class Simulator:
    """Truth and platforms for one scenario run; draws only from its own ``rng``."""

    def __init__(self, scenario: Scenario, rng: np.random.Generator):
        self.scenario = scenario
        self.rng = rng
        self.dt = scenario.dt
        self.model = build_motion_model(scenario.target.motion)
        tgt = scenario.target
        if tgt.initial_state is not None:
            self.truth = np.array(tgt.initial_state, dtype=float)
        else:
            L = np.linalg.cholesky(tgt.prior.covariance())
            self.truth = np.array(tgt.prior.mean) + L @ rng.standard_normal(len(tgt.prior.mean))
        self._init_platforms(scenario)

    def _init_platforms(self, scenario: Scenario) -> None:
        """Platforms, sensors and the sensor gating (no random draws)."""
        self.platforms: dict[str, _Platform] = {}
        # sensor id -> (platform id, model)
        self.sensors: dict[str, tuple[str, SensorModel]] = {}
        for p in scenario.platforms:
            self.platforms[p.id] = _Platform(
                p.id,
                np.array(p.initial_state, dtype=float),
                p.controllable,
                p.limits,
                tuple(s.id for s in p.sensors),
            )
            for s in p.sensors:
                self.sensors[s.id] = (p.id, build_sensor(s))
        self.epoch = 0
        self.selected: tuple[str, ...] | None = None  # None: every sensor measures
        self.measuring = {pid: True for pid in self.platforms}  # stop-and-measure gating

    @property
    def time(self) -> float:
        return self.epoch * self.dt

    @property
    def finished(self) -> bool:
        return self.epoch >= self.scenario.steps

    @property
    def controllable_ids(self) -> tuple[str, ...]:
        return tuple(p.id for p in self.platforms.values() if p.controllable)

    def truth_pv(self) -> np.ndarray:
        return self.model.kinematics(self.truth)

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

    def advance(self) -> list[Measurement]:
        """Simulate epoch k+1: truth, platform legs, then one Measurement per active sensor."""
        if self.finished:
            raise RuntimeError(f"the scenario has only {self.scenario.steps} steps")
        self.epoch += 1
        self.truth = self.model.sample(self.truth, self.dt, self.rng)
        self._move_platforms()
        target_pv = self.truth_pv()
        t = self.time
        out = []
        for sensor_id, (platform_id, sensor) in self.sensors.items():
            if self.selected is not None and sensor_id not in self.selected:
                continue
            if not self.measuring[platform_id]:
                continue
            s_pv = self.platforms[platform_id].pv
            detected = bool(sensor.detect(target_pv, s_pv, self.rng))
            z = sensor.sample(target_pv, s_pv, self.rng) if detected else None
            out.append(Measurement(sensor, s_pv.copy(), z, t, sensor_id))
        return out

    def _move_platforms(self) -> None:
        """Every platform flies its constant-velocity leg to the next epoch."""
        for p in self.platforms.values():
            p.pv = p.pv + self.dt * np.array([p.pv[1], 0.0, p.pv[3], 0.0])

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
        if not p.controllable or p.limits is None:
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

    def apply_selection(self, sensor_ids: Sequence[str] | None) -> None:
        """Only these sensors measure from the next epoch on (None: all of them)."""
        if sensor_ids is None:
            self.selected = None
            return
        unknown = [s for s in sensor_ids if s not in self.sensors]
        if unknown:
            raise ValueError(f"sensor ids must be among {sorted(self.sensors)}, got {unknown}")
        self.selected = tuple(sensor_ids)
